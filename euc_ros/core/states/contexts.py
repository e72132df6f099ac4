"""Reconstructed recordings as the model's evaluation contexts.

The valid samples of each run as a :class:`~euc_ros.core.model.effects.ModelContext` (decimated to an analysis
rate, :func:`decimation_step`), with the hooks some effects need: the rider CoG shifted in time
(``phi_shift``), the floor's slope under the wheel, the path travelled. The residual analysis and the
identification with an extended model evaluate their models on these.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from euc_ros.core.filters.derivatives import savgol_coefficients, savgol_derivatives
from euc_ros.core.model.candidate import ModelContext
from euc_ros.core.model.terms import EucParams
from euc_ros.core.states.floor import FloorFit, slope_along_path
from euc_ros.core.states.geometry import to_moving_frame
from euc_ros.core.states.kinematics import RiderStates

#: Length of the blocks the paired test compares [s] (longer than the derivative filter's window).
DEFAULT_BLOCK_S = 1.0


#: Sample rate the analysis works at [Hz] (:func:`decimation_step`): 4x the derivative filter's passband.
ANALYSIS_RATE_HZ = 10.0


@dataclass
class Recording:
    """One recording prepared for the analysis: its valid samples as a model context.

    Parameters
    ----------
    name : str
        Recording name.
    ctx : ModelContext
        The valid (and kept, after decimation) samples, with the effects' hooks in ``ctx.extras``.
    block : numpy.ndarray of int (m,)
        Block index of each sample (for the paired test and single-run folds).
    index : numpy.ndarray of int (m,), optional
        Index in the recording of each sample.
    """

    name: str
    ctx: ModelContext
    block: np.ndarray  # block index of each sample (for the paired test and single-run folds)
    index: np.ndarray | None = None  # sample index in the recording of each valid sample


#: Samples per block of the time-shift hook's geometry (:func:`hinge_path`, :func:`_phi_about_hinge`): the
#: temporaries of the whole recording's (n, 3) rotations were ~60 MB an hour at 120 Hz.
_SHIFT_BLOCK = 1 << 16


def hinge_path(st: RiderStates, l0: float) -> np.ndarray:
    """Ankle hinge A = C - l0 z_E (n, 3), z_E = Rz(psi) Rx(theta) Ry(gamma) e_z the EUC body's z axis.

    Computed block by block: elementwise, so the same numbers as the whole at once.

    Parameters
    ----------
    st : RiderStates
        The states (``C`` [m], ``gamma``, ``psi``, ``theta`` [rad]).
    l0 : float
        Distance from the wheel centre to the ankle hinge [m].

    Returns
    -------
    numpy.ndarray (n, 3)
        A [m], in the world frame.
    """
    n = st.C.shape[0]
    out = np.empty((n, 3))
    for lo in range(0, n, _SHIFT_BLOCK):
        hi = min(n, lo + _SHIFT_BLOCK)
        gamma, psi, theta = st.gamma[lo:hi], st.psi[lo:hi], st.theta[lo:hi]
        zb = np.stack([np.sin(gamma), -np.sin(theta) * np.cos(gamma), np.cos(theta) * np.cos(gamma)], axis=1)
        zw = np.stack([np.cos(psi) * zb[:, 0] - np.sin(psi) * zb[:, 1],
                       np.sin(psi) * zb[:, 0] + np.cos(psi) * zb[:, 1], zb[:, 2]], axis=1)
        out[lo:hi] = st.C[lo:hi] - l0 * zw
    return out


def _phi_about_hinge(G: np.ndarray, A: np.ndarray, psi: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rider pitch of G about A in the moving frame, ``arctan2(r_x, r_z)`` of ``r = T(G - A)`` (n,), block by block."""
    n = G.shape[0]
    out = np.empty(n)
    for lo in range(0, n, _SHIFT_BLOCK):
        hi = min(n, lo + _SHIFT_BLOCK)
        r = to_moving_frame(G[lo:hi] - A[lo:hi], psi[lo:hi], theta[lo:hi])
        out[lo:hi] = np.arctan2(r[:, 0], r[:, 2])
    return out


def _phi_about_hinge_turned(G: np.ndarray, A: np.ndarray, trig: tuple) -> np.ndarray:
    """:func:`_phi_about_hinge` with the moving frame's ``(cos psi, sin psi, cos theta, sin theta)`` given.

    The arithmetic of :func:`~euc_ros.core.states.geometry.to_moving_frame`, so the same numbers.
    """
    cp, sp, ct, st = trig
    n = G.shape[0]
    out = np.empty(n)
    for lo in range(0, n, _SHIFT_BLOCK):
        hi = min(n, lo + _SHIFT_BLOCK)
        v = G[lo:hi] - A[lo:hi]
        x1 = cp[lo:hi] * v[:, 0] + sp[lo:hi] * v[:, 1]
        y1 = -sp[lo:hi] * v[:, 0] + cp[lo:hi] * v[:, 1]
        out[lo:hi] = np.arctan2(x1, -st[lo:hi] * y1 + ct[lo:hi] * v[:, 2])
    return out


def _phi_shift_fn(st: RiderStates, params: EucParams, window: int, polyorder: int, valid: np.ndarray
                  ) -> Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Build dt -> change of (phi, phi_dot, phi_ddot) when the rider CoG G is shifted by dt in time.

    The hinge path, the unshifted pitch and the moving frame's sines and cosines (8 numbers a sample) are
    made on the first call and kept: every recording is prepared (the noise floor's re-noised ones too), few
    are shifted, and a fit shifts one many times.
    """
    t = st.t
    psi, theta = st.psi, st.theta
    idx = np.flatnonzero(valid)
    half = (window - 1) // 2
    base: dict = {}

    def geometry():
        if not base:
            A = hinge_path(st, params.l0)
            base["A"], base["phi0"] = A, _phi_about_hinge(st.G, A, psi, theta)
            base["trig"] = (np.cos(psi), np.sin(psi), np.cos(theta), np.sin(theta))
            uniform = st.frame is not None and len(st.frame) == len(t) and bool(np.all(np.diff(st.frame) == 1)) \
                and np.isfinite(st.dt)
            # the filter's centre weights evaluated only at the samples the analysis uses: those of a whole
            # window; the valid samples nearer a stretch's end (fits through a gap, the take's one-sided ends)
            # see a missing or padded sample and come out NaN, which the time-offset effect leaves out (its mask)
            base["weights"] = savgol_coefficients(window, polyorder, st.dt, [half])[:, 0, :] if uniform else None
        return base["A"], base["phi0"], base["weights"], base["trig"]

    def shift(dt: float):
        A, phi0, weights, trig = geometry()
        Gs = np.stack([np.interp(t + dt, t, st.G[:, k], left=np.nan, right=np.nan) for k in range(3)], axis=1)
        d = _phi_about_hinge_turned(Gs, A, trig)
        d -= phi0
        if weights is not None:
            W = np.lib.stride_tricks.sliding_window_view(np.pad(d, half, constant_values=np.nan), window)[idx]
            out = W @ weights.T
            return out[:, 0], out[:, 1], out[:, 2]
        der = savgol_derivatives(t, d, window=window, polyorder=polyorder, frame=st.frame)
        return der.y[valid], der.y_dot[valid], der.y_ddot[valid]

    shift.forget = base.clear       # drops the kept geometry (made again, the same, if the hook is called again)
    return shift


def forget_shift_caches(recs: Sequence[Recording]) -> None:
    """Let the time-shift hooks of prepared recordings drop what they keep (:func:`_phi_shift_fn`: 8 numbers a sample).

    For example once the analysis no longer fits a time offset; a hook called again makes it again.

    Parameters
    ----------
    recs : sequence of Recording
        Recordings of :func:`prepare`; those without a time-shift hook are left as they are.
    """
    for rec in recs:
        forget = getattr(rec.ctx.extras.get("phi_shift"), "forget", None)
        if forget is not None:
            forget()


def decimation_step(dt: float, analysis_rate_hz: float | None) -> int:
    """Keep every k-th sample so that the analysis runs at about ``analysis_rate_hz`` (1: all samples).

    The states come out of the Savitzky-Golay filter, whose passband ends near 2.5 Hz for the default
    1.2 s window (response below 1 % of its peak from 2.6 Hz on, sidelobes of 6-22 % above it): the
    residual's signal is over-sampled at 120-360 Hz and a sub-sample at :data:`ANALYSIS_RATE_HZ` keeps it
    (the fits and held-out errors on the sub-sample are unbiased; measured against every sample in
    ``test_decimation.py``), while the fits' cost falls with the number of samples.

    Parameters
    ----------
    dt : float
        Sample spacing [s].
    analysis_rate_hz : float or None
        Wanted rate [Hz]; None or 0 keeps every sample.

    Returns
    -------
    int
        The step k, ``>= 1`` (1 also when ``dt`` is not a finite positive number).
    """
    if not analysis_rate_hz or not np.isfinite(dt) or dt <= 0:
        return 1
    return max(1, int(math.floor(1.0 / (dt * analysis_rate_hz) + 1e-9)))


def analysis_rate(window_s: float, polyorder: int) -> float:
    """Analysis rate [Hz] for states of a Savitzky-Golay filter: :data:`ANALYSIS_RATE_HZ` scaled with its passband.

    The second derivative of a window of ``T`` seconds and order ``p`` follows a sinusoid up to about
    ``(p + 2) / (2 T)`` Hz; the rate keeps the ratio of :data:`ANALYSIS_RATE_HZ` to the passband of the
    residual's default filter (1.2 s, order 6), and never goes below :data:`ANALYSIS_RATE_HZ`.

    Parameters
    ----------
    window_s : float
        Window [s].
    polyorder : int
        Order.

    Returns
    -------
    float

    Examples
    --------
    >>> analysis_rate(1.2, 6), analysis_rate(0.6, 6), analysis_rate(2.4, 6)
    (10.0, 20.0, 10.0)
    """
    passband = (int(polyorder) + 2) / (2.0 * float(window_s))
    return max(ANALYSIS_RATE_HZ, ANALYSIS_RATE_HZ * passband / _DEFAULT_PASSBAND_HZ)


#: Passband of the residual's default filter, 1.2 s and order 6 [Hz] (:func:`analysis_rate`).
_DEFAULT_PASSBAND_HZ = 8 / 2.4


def prepare(states: Sequence[RiderStates], params: EucParams, *, block_s: float = DEFAULT_BLOCK_S,
            floor: FloorFit | None = None, analysis_rate_hz: float | None = None) -> list[Recording]:
    """Turn reconstructed recordings into analysis inputs (valid samples, yaw rate, time-shift hook).

    ``analysis_rate_hz``: keep every k-th sample (:func:`decimation_step`); None keeps all of them.

    With a ``floor`` that is not flat, each context also carries the floor's slope along travel under
    the wheel (``extras['floor_a']``) and the wheel centre's vertical acceleration (``extras['c_zdd']``,
    the states' derivative filter) for :class:`~euc_ros.core.model.effects.FloorGeometry`.

    Each context's full-rate signals (``extras['full']``, :class:`FullSignals`) are read from its states when
    needed (the contexts keep their states: the time-shift hook works on them).

    Parameters
    ----------
    states : sequence of RiderStates
        The reconstructed recordings.
    params : EucParams
        Model parameters the contexts carry.
    block_s : float
        Length of the paired test's blocks [s].
    floor : FloorFit, optional
        The floor; one that is not flat adds the slope hooks.
    analysis_rate_hz : float, optional
        Analysis rate [Hz].

    Returns
    -------
    list of Recording
        One per recording, in order.
    """
    out = []
    for st in states:
        window = st.window if st.window and st.window % 2 == 1 else 9
        valid = np.asarray(st.valid, bool).copy()
        dpsi = savgol_derivatives(st.t, np.unwrap(st.psi), window=window, polyorder=st.polyorder, frame=st.frame)
        valid &= np.isfinite(dpsi.y_dot) & np.isfinite(st.theta)
        step = decimation_step(st.dt if np.isfinite(st.dt) else float(np.median(np.diff(st.t))), analysis_rate_hz)
        if step > 1:
            valid &= (np.arange(valid.size) % step) == 0
        ctx = ModelContext(
            t=st.t[valid] - st.t[0], x_dot=st.x_dot[valid], x_ddot=st.x_ddot[valid], gamma=st.gamma[valid],
            gamma_dot=st.gamma_dot[valid], gamma_ddot=st.gamma_ddot[valid], phi=st.phi[valid],
            phi_dot=st.phi_dot[valid], phi_ddot=st.phi_ddot[valid], psi=np.unwrap(st.psi)[valid],
            psi_dot=dpsi.y_dot[valid], theta=st.theta[valid], params=params)
        if st.phi_definition == "hinge":
            ctx.extras["phi_shift"] = _phi_shift_fn(st, params, window, st.polyorder, valid)
        if floor is not None and not floor.flat:
            a = slope_along_path(st.C, st.theta, st.psi, st.valid, params.R, floor)
            czz = savgol_derivatives(st.t, st.C[:, 2], window=window, polyorder=st.polyorder, frame=st.frame).y_ddot
            ctx.extras["floor_a"] = np.nan_to_num(a[valid])
            ctx.extras["c_zdd"] = np.nan_to_num(czz[valid])
        dt = st.dt if np.isfinite(st.dt) else float(np.median(np.diff(st.t)))
        block = np.floor((st.t[valid] - st.t[0]) / max(block_s, dt)).astype(int)
        xd = np.nan_to_num(st.x_dot)
        s_path = np.concatenate([[0.0], np.cumsum(0.5 * (xd[1:] + xd[:-1]) * np.diff(st.t))])
        ctx.extras["path_s"] = s_path[valid]
        ctx.extras["lab_x"] = np.nan_to_num(st.C[valid, 0])
        ctx.extras["lab_y"] = np.nan_to_num(st.C[valid, 1])
        ctx.extras["recording"] = st.name
        # the full-rate signals and the states' filter, for basis functions made as the states were
        # (:mod:`euc_ros.core.residual.families`: a force reaches the residual through that filter)
        ctx.extras["full"] = FullSignals(st, np.flatnonzero(valid), int(window))
        out.append(Recording(st.name, ctx, block, np.flatnonzero(valid)))
    return out


class FullSignals(Mapping):
    """A context's full-rate signals (every sample of the recording, NaN as 0), made from its states when read.

    ``t`` (from the first sample), ``v`` (x_dot), ``s`` (path), ``psi`` (unwrapped), ``X``, ``Y`` (the wheel
    centre), ``phi_dot``, ``gamma_dot``, and ``index`` (the analysed samples), ``window``, ``polyorder`` (the
    states' filter). A reference to the states, not copies of eight of their arrays: those are read a few
    times per analysis, while the contexts live through it.

    Parameters
    ----------
    st : RiderStates
        The recording's states.
    index : numpy.ndarray of int (m,)
        Indices of the analysed samples.
    window : int
        The states' filter window [samples].
    """

    _KEYS = ("t", "v", "s", "psi", "X", "Y", "phi_dot", "gamma_dot", "index", "window", "polyorder")

    def __init__(self, st: RiderStates, index: np.ndarray, window: int) -> None:
        self._st, self._index, self._window = st, index, window

    def __getitem__(self, key: str):
        st = self._st
        if key == "t":
            return st.t - st.t[0]
        if key in ("v", "s"):
            xd = np.nan_to_num(st.x_dot)
            if key == "v":
                return xd
            return np.concatenate([[0.0], np.cumsum(0.5 * (xd[1:] + xd[:-1]) * np.diff(st.t))])
        if key == "psi":
            return np.nan_to_num(np.unwrap(st.psi))
        if key in ("X", "Y"):
            return np.nan_to_num(st.C[:, 0 if key == "X" else 1])
        if key in ("phi_dot", "gamma_dot"):
            return np.nan_to_num(getattr(st, key))
        if key == "index":
            return self._index
        if key == "window":
            return self._window
        if key == "polyorder":
            return int(st.polyorder)
        raise KeyError(key)

    def __iter__(self):
        return iter(self._KEYS)

    def __len__(self) -> int:
        return len(self._KEYS)
