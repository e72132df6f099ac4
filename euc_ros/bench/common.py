"""Shared machinery of the benchmarks: figures, isolated measurements, peak memory, machine facts.

A benchmark returns a dict::

    {"name": "csv_parse", "title": "...", "figures": [figure(...), ...], "peak_rss_mb": {...},
     "details": {...}, "wall_s": ...}

Every figure carries its floor (measured in the same run) and the *cost ratio*
``value / floor`` for costs (latency, time) or ``floor / value`` for rates (messages per second,
real-time factor): 1 means as cheap as the floor, 2 means twice the floor's cost.

In-process measurements run through :meth:`BenchContext.isolated`: a fresh interpreter
(``python -m euc_ros.bench.worker``) calls one function and reports its result with the peak RSS
of that process (``resource.getrusage``), so each figure's memory is its own. Child processes of
the live benchmarks are sampled with :class:`PeakRssSampler` (``VmHWM`` of ``/proc/<pid>/status``,
the kernel's own high-water mark, so short peaks between samples are not missed).
"""
from __future__ import annotations

import contextlib
import importlib
import json
import os
import platform
import resource
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from euc_ros.core.errors import EucError
from euc_ros.ros.launcher import Launcher

#: Default cache of generated recordings (reused between runs).
DEFAULT_CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "euc_ros" / "bench"


class BenchError(EucError):
    """A benchmark could not run (a process failed, a measurement timed out)."""


def figure(metric: str, value: float, unit: str, *, floor: float | None = None, lower_is_better: bool = True,
           target: str | None = None, met: bool | None = None, note: str | None = None) -> dict:
    """One figure of a benchmark with its floor and cost ratio.

    Parameters
    ----------
    metric : str
        What is measured (``"end-to-end p99"``).
    value : float
        The measured value, in ``unit``.
    unit : str
        ``"ms"``, ``"frames/s"``, ``"x real time"``...
    floor : float, optional
        The floor's value in the same unit (None where the figure has no floor, e.g. a count).
    lower_is_better : bool
        True for costs (the ratio is value / floor), False for rates (floor / value).
    target : str, optional
        The target as text (``"<= 2x floor"``); ``met`` says whether it was met.
    """
    ratio = None
    if floor is not None and value is not None and 0 < value < np.inf and 0 < floor < np.inf:
        ratio = float(value / floor) if lower_is_better else float(floor / value)
    return {"metric": metric, "value": None if value is None else float(value), "unit": unit,
            "floor": None if floor is None else float(floor), "ratio": ratio, "target": target,
            "met": None if met is None else bool(met), "note": note}


def percentiles_ms(latency_ns: np.ndarray) -> dict:
    """p50, p99, max and count of latencies given in ns, in ms (NaN when empty)."""
    a = np.asarray(latency_ns, dtype=float) * 1e-6
    if a.size == 0:
        return {"p50": float("nan"), "p99": float("nan"), "max": float("nan"), "n": 0}
    return {"p50": float(np.percentile(a, 50)), "p99": float(np.percentile(a, 99)), "max": float(a.max()),
            "n": int(a.size)}


def self_peak_rss_mb() -> float:
    """Peak resident set size of this process image so far [MB].

    ``VmHWM`` of ``/proc/self/status``: the high-water mark of the current address space. Not
    ``ru_maxrss``, which survives ``exec`` and so starts at the RSS of the parent that spawned the
    process (vfork shares the parent's address space until the exec).
    """
    kb = _vm_hwm_kb(os.getpid())
    if kb is None:
        kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss   # KiB on Linux
    return kb / 1024.0


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU time of ``pid`` so far [s] (``/proc/<pid>/stat``), None where unreadable."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            text = f.read()
        fields = text[text.rindex(b")") + 2:].split()   # after "pid (comm) "; utime, stime are fields 14, 15
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def cpu_fraction(series: list[tuple[float, float]], t0: float, t1: float) -> float:
    """Mean CPU use (1 = one core) between wall times ``t0`` and ``t1``.

    From ``(wall time, CPU seconds)`` samples (interpolated); NaN without samples around the interval.

    Examples
    --------
    >>> round(cpu_fraction([(0.0, 0.0), (1.0, 0.25), (2.0, 0.75)], 0.5, 2.0), 3)
    0.417
    """
    if len(series) < 2 or t1 <= t0:
        return float("nan")
    t, c = (np.array(v, dtype=float) for v in zip(*series))
    if t0 < t[0] - 0.5 or t1 > t[-1] + 0.5:
        return float("nan")
    c0, c1 = np.interp([t0, t1], t, c)
    return float((c1 - c0) / (t1 - t0))


def _vm_hwm_kb(pid: int) -> int | None:
    return _status_kb(pid, b"VmHWM:")


def _status_kb(pid: int, key: bytes) -> int | None:
    try:
        with open(f"/proc/{pid}/status", "rb") as f:
            for line in f:
                if line.startswith(key):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return None


@contextlib.contextmanager
def peak_rss_increase():
    """Measure how far the block raises this process' resident set above its size at the start [MB].

    Yields a dict that is filled on exit: ``baseline_mb`` (``VmRSS`` at the start: the interpreter
    and its imports), ``peak_mb`` (``VmHWM`` at the end), ``increase_mb`` (their difference: the
    block's own peak memory) and ``hwm_reset``. The high-water mark is reset at the start by writing
    5 to ``/proc/self/clear_refs`` (Linux >= 4.0); where that is refused (``hwm_reset`` False) an
    earlier peak (of the imports, say) may count, and the increase is an upper bound. Without
    ``/proc`` the values are None.
    """
    out: dict[str, Any] = {"baseline_mb": None, "peak_mb": None, "increase_mb": None, "hwm_reset": False}
    pid = os.getpid()
    base = _status_kb(pid, b"VmRSS:")
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
            f.write("5")
        out["hwm_reset"] = True
    except OSError:
        pass
    try:
        yield out
    finally:
        peak = _vm_hwm_kb(pid)
        if base is not None and peak is not None:
            out.update(baseline_mb=round(base / 1024.0, 1), peak_mb=round(peak / 1024.0, 1),
                       increase_mb=round((peak - base) / 1024.0, 1))


def _program_label(cmd: list[str]) -> str:
    """A short label of a command line: console script or ``module mode`` of ``python -m``."""
    name = Path(cmd[0]).name
    if name.startswith("python") and len(cmd) > 1:
        if cmd[1] == "-m" and len(cmd) > 2:
            rest = [a for a in cmd[3:4] if not a.startswith("-")]
            return " ".join([cmd[2].rsplit(".", 1)[-1], *rest])
        if not cmd[1].startswith("-"):
            return Path(cmd[1]).name
    return name


class PeakRssSampler:
    """Sample the peak RSS of labelled processes in a background thread.

    ``VmHWM`` (the kernel's high-water mark) is read every ``period_s``; the last value read before
    a process exits is its peak up to that moment (within one period of its end). Where
    ``/proc/<pid>/status`` is unavailable, psutil's current RSS is sampled instead.
    """

    def __init__(self, period_s: float = 0.2, *, children_of: int | None = None) -> None:
        self.period_s = period_s
        self.children_of = children_of
        self.pids: dict[str, int] = {}
        self.peak_kb: dict[str, int] = {}
        #: label -> [(wall time [s], CPU seconds)], one entry per sample while the process lives
        self.cpu: dict[str, list[tuple[float, float]]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def add(self, label: str, pid: int) -> None:
        """Watch ``pid`` under ``label``."""
        self.pids[label] = pid

    def _discover(self) -> None:
        """Watch every descendant of ``children_of`` (labelled by program name) as it appears."""
        import psutil

        try:
            kids = psutil.Process(self.children_of).children(recursive=True)
        except psutil.Error:
            return
        known = set(self.pids.values())
        for p in kids:
            if p.pid in known:
                continue
            try:
                cmd = p.cmdline()
            except psutil.Error:
                continue
            name = _program_label(cmd) if cmd else p.name()
            label, i = name, 2
            while label in self.pids:
                label, i = f"{name} #{i}", i + 1
            self.pids[label] = p.pid

    def _sample(self) -> None:
        if self.children_of is not None:
            self._discover()
        for label, pid in list(self.pids.items()):
            cpu = cpu_seconds(pid)
            if cpu is not None:
                self.cpu.setdefault(label, []).append((time.time(), cpu))
            kb = _vm_hwm_kb(pid)
            if kb is None:
                try:
                    import psutil

                    kb = psutil.Process(pid).memory_info().rss // 1024
                except Exception:   # the process is gone
                    continue
            if kb > self.peak_kb.get(label, 0):
                self.peak_kb[label] = kb

    def _run(self) -> None:
        while not self._stop.is_set():
            self._sample()
            self._stop.wait(self.period_s)

    def __enter__(self) -> "PeakRssSampler":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)

    def peaks_mb(self) -> dict[str, float]:
        """Peak RSS per label [MB]."""
        return {k: round(v / 1024.0, 1) for k, v in self.peak_kb.items()}


@contextlib.contextmanager
def environ(values: dict):
    """Set environment variables for the block (and the processes it starts); restore them after."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update({k: str(v) for k, v in values.items()})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def pinned_to_one_core():
    """Run the block on one CPU (the last allowed one) where the OS allows it; yields the CPU or None."""
    if not hasattr(os, "sched_setaffinity"):
        yield None
        return
    old = os.sched_getaffinity(0)
    cpu = max(old)
    try:
        os.sched_setaffinity(0, {cpu})
    except OSError:
        yield None
        return
    try:
        yield cpu
    finally:
        os.sched_setaffinity(0, old)


def git_commit(repo: Path | None = None) -> str | None:
    """The checked-out commit of the repository holding this package (None outside git)."""
    repo = repo or Path(__file__).resolve().parents[2]
    try:
        out = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=5)
        dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.TimeoutExpired):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def machine_info() -> dict:
    """What the figures depend on: CPU, cores, memory, load, OS, versions, commit."""
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info: dict[str, Any] = {
        "cpu": cpu, "logical_cpus": os.cpu_count(),
        "cpus_allowed": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "os": f"{platform.system()} {platform.release()}", "python": platform.python_version(),
        "numpy": np.__version__, "load_average": [round(x, 2) for x in os.getloadavg()],
        "commit": git_commit(),
    }
    try:
        import psutil

        info["memory_gb"] = round(psutil.virtual_memory().total / 2**30, 1)
    except ImportError:
        pass
    try:
        from importlib.metadata import version

        info["rclpy"] = version("ros-jazzy-rclpy")
    except Exception:
        info["rclpy"] = None
    return info


def resolve_target(target: str) -> Callable:
    """The function named ``module:function`` (imported now)."""
    module, sep, func = target.partition(":")
    if not sep or not module or not func:
        raise BenchError(f"expected module:function, got {target!r}")
    return getattr(importlib.import_module(module), func)


@dataclass
class BenchContext:
    """Settings shared by every benchmark of one run.

    Attributes
    ----------
    quick : bool
        Short variants (``--quick``): each benchmark on less data (shorter recordings and streams, fewer
        repeats, rides, cells and inputs) against the same floor; indicative figures.
    cache_dir : Path
        Generated recordings, reused between runs.
    tmp_dir : Path
        Scratch space of this run (bags, logs), removed by the caller.
    log : callable
        Progress lines (stderr by default).
    realtime : int, optional
        SCHED_FIFO priority of the latency-critical processes of the live benchmarks (``--realtime``).
    command : str
        The command-line entry point the offline benchmarks run in process, as ``module:function``
        (the function takes the argument list and returns an exit code). The caller names it
        (``euc-ros bench`` gives its own dispatcher), so the benchmarks depend on no command module.
    campaign : str
        The module of the campaign runner (``seed_tasks``, ``run_task``, ``run_campaign``), named by the
        caller for the same reason (``euc-ros bench`` gives ``euc_ros.cli.campaign_tasks``).
    """

    quick: bool
    cache_dir: Path
    tmp_dir: Path
    realtime: int | None = None
    command: str = ""
    campaign: str = ""
    log: Callable[[str], None] = field(default=lambda s: print(s, file=sys.stderr, flush=True))

    def isolated(self, target: str, timeout_s: float = 600.0, **kwargs) -> dict:
        """Call ``module:function(**kwargs)`` in a fresh interpreter; its dict result gains ``peak_rss_mb``.

        The function's keyword arguments and result must be JSON-serialisable.
        """
        req = self.tmp_dir / f"req_{time.monotonic_ns()}.json"
        out = req.with_suffix(".out.json")
        req.write_text(json.dumps({"target": target, "kwargs": kwargs}), encoding="utf-8")
        cmd = [sys.executable, "-m", "euc_ros.bench.worker", str(req), str(out)]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
        except subprocess.TimeoutExpired:
            raise BenchError(f"{target} did not finish within {timeout_s:g} s") from None
        if proc.returncode != 0 or not out.exists():
            tail = " | ".join((proc.stderr or proc.stdout).strip().splitlines()[-5:])
            raise BenchError(f"{target} failed (exit {proc.returncode}): {tail}")
        return json.loads(out.read_text(encoding="utf-8"))


def run_launched(specs, timeout_s: float, log):
    """Launch ``specs`` (euc_ros.ros.launcher), sampling each process' peak RSS, until done or ``timeout_s``.

    Returns ``(launcher, finished, peaks_mb)``; the processes are stopped on return.
    """
    launcher, finished, sampler = run_launched_sampled(specs, timeout_s, log)
    return launcher, finished, sampler.peaks_mb()


def run_launched_sampled(specs, timeout_s: float, log, period_s: float = 0.2):
    """:func:`run_launched` returning the :class:`PeakRssSampler` itself (peak RSS and CPU series)."""
    launcher = Launcher(specs, stream=log)
    with PeakRssSampler(period_s) as rss:
        with launcher:
            for label, proc in launcher.procs.items():
                rss.add(label, proc.pid)
            finished = launcher.wait(timeout=timeout_s)
    return launcher, finished, rss
