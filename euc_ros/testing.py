"""Helpers for tests: bounded waits that never hang, and round-off bounds for numerical tolerances.

Tolerances of the tests come from the computation, never from one machine's output (CI may run on
any x86-64 CPU, whose BLAS kernels sum in another order). :func:`savgol_roundoff` bounds the
round-off of a Savitzky-Golay derivative, the one computation of the pipeline that amplifies the
round-off of its inputs by orders of magnitude (a second derivative over a 0.2 s window at 120 Hz
multiplies it by ~5000 s^-2).
"""
from __future__ import annotations

import importlib.util
import math
import time
from pathlib import Path
from types import ModuleType
from typing import Callable

import numpy as np

#: Machine epsilon of IEEE double precision (2.2e-16): the spacing of doubles just above 1.
EPS = float(np.finfo(float).eps)


def wait_for(predicate: Callable[[], bool], timeout_s: float, period_s: float = 0.02) -> bool:
    """Poll ``predicate`` until it is true or ``timeout_s`` passes; return its last value."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period_s)
    return bool(predicate())


def spin_until(node, predicate: Callable[[], bool], timeout_s: float, executor=None) -> bool:
    """Spin ``node`` (in its own context) until ``predicate`` holds or ``timeout_s`` passes."""
    from rclpy.executors import SingleThreadedExecutor

    ex = executor or SingleThreadedExecutor(context=node.context)
    ex.add_node(node)
    try:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return True
            ex.spin_once(timeout_sec=0.02)
        return bool(predicate())
    finally:
        ex.remove_node(node)


def spin_executor_until(executor, predicate: Callable[[], bool], timeout_s: float, what: str = "condition") -> None:
    """Spin ``executor`` until ``predicate`` holds; fail the test if it does not within ``timeout_s``.

    Parameters
    ----------
    executor : rclpy.executors.Executor
        The executor of the nodes under test, spun once per 5 ms at the most.
    predicate : callable
        Checked before every spin.
    timeout_s : float
        How long to spin [s].
    what : str
        What is waited for, named in the assertion's message.

    Raises
    ------
    AssertionError
        ``timed out waiting for <what>``.
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        executor.spin_once(timeout_sec=0.005)
    assert predicate(), f"timed out waiting for {what}"


def load_module(path: str | Path, name: str) -> ModuleType:
    """Load a Python file as a new module (one test file's helpers and fixtures used by another).

    The tests run with ``--import-mode=importlib``, where a test file cannot import another; each call
    executes the file again, as a module of its own named ``name`` (not entered in ``sys.modules``).

    Parameters
    ----------
    path : str or Path
        The file.
    name : str
        The module's ``__name__``.

    Returns
    -------
    ModuleType
    """
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def savgol_coefficients(window: int, polyorder: int, deriv: int, dt: float, pos: int | None = None) -> np.ndarray:
    """Savitzky-Golay coefficients ``h`` with ``y^(deriv)(t_pos) = sum_k h_k y_k`` (``use="dot"`` order).

    An independent construction for the tests: the least-squares fit is set up in the normalised time
    ``u = (k - pos) / half`` (``half = (window - 1) / 2``), whose Vandermonde matrix is well
    conditioned at any window, and solved by the pseudo-inverse.
    """
    half = (window - 1) // 2
    pos = half if pos is None else pos
    u = (np.arange(window) - pos) / half
    vander = np.vander(u, polyorder + 1, increasing=True)
    return np.linalg.pinv(vander)[deriv] * math.factorial(deriv) / (half * dt) ** deriv


def savgol_roundoff(window: int, polyorder: int, deriv: int, dt: float, scale: float, *, pos: int | None = None,
                    input_ulps: float = 4.0) -> float:
    """Bound on the round-off error of one Savitzky-Golay derivative of samples of magnitude ``scale``.

    A filter output is ``sum_k h_k y_k`` over ``window`` samples. On data the fit reproduces exactly (a
    polynomial of degree <= ``polyorder``) its whole error is round-off, from three sources:

    1. the coefficients: a backward-stable least-squares solve in a normalised time variable gives
       ``||dh||_1 <= kappa eps ||h||_1`` with ``kappa`` the condition number of the window's
       Vandermonde matrix (~20 for order 4, ~100 for order 6, at any window), so the output moves by
       at most ``kappa eps sum|h| max|y|`` (this is the term an unnormalised fit blows up: ``kappa``
       ~ ``half^polyorder``);
    2. the sum of ``window`` products: at most ``window eps sum|h_k y_k|`` (Higham's ``gamma_n``);
    3. the inputs: samples that carry ``input_ulps`` ulps of ``scale`` each (the arithmetic that
       produced them), amplified by ``sum|h|``.

    Together: ``(kappa + window + input_ulps) eps sum|h| scale``. ``scale`` must bound ``|y_k|`` over
    the window (the absolute values, not the variation: a signal 16 m from the origin carries the
    round-off of 16 m).

    Parameters
    ----------
    window, polyorder, deriv : int
        Filter window [samples], order and derivative (0, 1, 2).
    dt : float
        Sample spacing [s].
    scale : float
        Largest ``|y|`` in the window [unit of y].
    pos : int, optional
        Sample of the window the fit is evaluated at (default: the centre; ``window - 1`` for a causal
        filter).
    input_ulps : float
        Round-off the inputs carry, in units of ``eps * scale``.

    Returns
    -------
    float
        [unit of y / s^deriv]
    """
    half = (window - 1) // 2
    u = (np.arange(window) - (half if pos is None else pos)) / half
    kappa = float(np.linalg.cond(np.vander(u, polyorder + 1, increasing=True)))
    h = savgol_coefficients(window, polyorder, deriv, dt, pos)
    return (kappa + window + input_ulps) * EPS * float(np.abs(h).sum()) * float(scale)
