"""Online companions of the identification: a sliding-window RMSE and a sliding-window estimate of h.

Both are fed one sample at a time (the torque_estimator node calls them at the mocap rate, after the
fixed-lag Savitzky-Golay filter) and return their current value; they hold no clock and no ROS.

:class:`OnlineHEstimator` keeps, for the last ``window`` valid samples, the six coefficients of the
residual ``e(h) = c (a0 + a1 h + a2 h^2) / (d0 + d1 h)`` (see :mod:`euc_ros.core.identify.fit`), so
the sum of squares ``S(h) = sum e^2`` over the window is exact for any h at O(window) cost. Each update
takes the minimum of S on a coarse grid over the bounds, then refines it with Gauss-Newton steps. The
standard deviation is the nonlinear least-squares one, ``sigma_h^2 = k s^2 / sum e'(h)^2`` with
``s^2 = S / (n - 1)`` and ``k`` the number of correlated samples per independent one
(``correlation_samples``; the Savitzky-Golay window is a fair value, since smoothing correlates
neighbouring residuals). The estimate is NaN until the window holds ``min_samples`` samples and the
data excite h: the RMS sensitivity ``sqrt(mean(e'^2))`` [N m per m of h] must reach
``min_sensitivity``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.fit import model_params, residual_coefficients
from euc_ros.core.model.terms import EucParams


class SlidingRmse:
    """RMS of the last ``window`` finite values pushed (NaN values are skipped, not counted).

    Parameters
    ----------
    window : int
        Number of most recent pushes considered (a NaN push still ages the window).

    Raises
    ------
    ConfigError
        When ``window`` is not a positive integer.

    Examples
    --------
    >>> r = SlidingRmse(2)
    >>> [round(r.push(v), 6) for v in (3.0, 4.0, float("nan"))]
    [3.0, 3.535534, 4.0]
    """

    def __init__(self, window: int) -> None:
        if int(window) != window or window < 1:
            raise ConfigError(f"window must be a positive integer, got {window!r}", key="window")
        self.window = int(window)
        self._buf = np.zeros(self.window)
        self._ok = np.zeros(self.window, dtype=bool)
        self._i = 0
        self._sum = 0.0
        self._count = 0
        self._pushes = 0

    def push(self, value: float) -> float:
        """Add one value [N m] and return the current RMS [N m] (NaN while no finite value is held).

        Parameters
        ----------
        value : float
            The value [N m]; a non-finite value is held as missing.

        Returns
        -------
        float
            The RMS over the finite values in the window [N m].
        """
        j = self._i
        if self._ok[j]:
            self._sum -= self._buf[j] ** 2
            self._count -= 1
        ok = bool(np.isfinite(value))
        self._buf[j] = value if ok else 0.0
        self._ok[j] = ok
        if ok:
            self._sum += float(value) ** 2
            self._count += 1
        self._i = (j + 1) % self.window
        self._pushes += 1
        if self._pushes % self.window == 0:  # refresh the running sum (no drift)
            self._sum = float(np.sum(self._buf[self._ok] ** 2))
        return self.value

    @property
    def value(self) -> float:
        """Current RMS [N m]."""
        return float(np.sqrt(max(self._sum, 0.0) / self._count)) if self._count else float("nan")

    @property
    def count(self) -> int:
        """Finite values in the window."""
        return self._count

    def reset(self) -> None:
        """Forget everything."""
        self.__init__(self.window)


@dataclass(frozen=True)
class HEstimate:
    """Current online estimate of the CoG height.

    Parameters
    ----------
    h_m : float
        Estimate [m]; NaN until enough samples and excitation.
    h_std_m : float
        Its standard deviation [m] (NaN likewise).
    rmse_nm : float
        RMSE of ``M_d1 - M_d2`` over the window at ``h_m`` [N m].
    n_samples : int
        Valid samples in the window.
    sensitivity_nm_per_m : float
        RMS derivative of the residual with respect to h [N m / m] (the excitation).
    """

    h_m: float
    h_std_m: float
    rmse_nm: float
    n_samples: int
    sensitivity_nm_per_m: float


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """``a . b`` without BLAS.

    OpenBLAS's ddot starts its thread pool above ~10 000 elements (30 s at 360 Hz), whose spinning threads
    took a second core from a live node on a 2-core machine.
    """
    return float(np.einsum("i,i->", a, b))


#: Most samples the coarse grid of :class:`OnlineHEstimator` evaluates (Gauss-Newton then uses all).
GRID_SAMPLES = 1500
#: Between two coarse-grid searches, an update starts Gauss-Newton from the previous estimate (the
#: window moved by ``update_every`` samples, so the minimum moved little): the grid is searched again
#: every this many updates, when there is no previous estimate, or when Gauss-Newton ends on a bound.
REGRID_EVERY = 50
#: Gauss-Newton stops when its step is below this [m] (a micrometre; the estimate's
#: own standard deviation is millimetres).
GN_TOL_M = 1e-6


class OnlineHEstimator:
    """Sliding-window least-squares estimate of h with its uncertainty (see the module docstring).

    Parameters
    ----------
    params : EucParams
        Nominal parameters (``h`` ignored).
    window : int
        Number of most recent samples used [samples] (invalid samples age the window too).
    model : {"3dof", "2dof"}
    h_bounds : (float, float)
        Search interval [m].
    min_samples : int, optional
        Valid samples needed before an estimate is given (default ``window // 4``).
    min_sensitivity : float
        Required RMS sensitivity of the residual to h [N m / m].
    correlation_samples : float
        Correlated samples per independent one, inflating the variance (>= 1).
    grid_points : int
        Size of the coarse grid over ``h_bounds``.
    update_every : int
        Re-estimate every this many samples (coefficients are stored at every sample).

    Raises
    ------
    ConfigError
        When ``window`` is below 3 samples, the h bounds are not ``0 < low < high``, or
        ``correlation_samples`` is below 1.
    """

    def __init__(self, params: EucParams, window: int, *, model: str = "3dof", h_bounds=(0.1, 1.2),
                 min_samples: int | None = None, min_sensitivity: float = 5.0, correlation_samples: float = 1.0,
                 grid_points: int = 45, update_every: int = 1) -> None:
        model_params(params, model)
        if int(window) != window or window < 3:
            raise ConfigError(f"window must be an integer >= 3 samples, got {window!r}", key="window")
        lo, hi = (float(v) for v in h_bounds)
        if not (0 < lo < hi):
            raise ConfigError(f"h bounds must satisfy 0 < low < high, got {h_bounds!r}", key="h_bounds")
        if correlation_samples < 1:
            raise ConfigError(f"correlation_samples must be >= 1, got {correlation_samples!r}",
                              key="correlation_samples")
        self.params = params
        self.model = model
        self.window = int(window)
        self.h_bounds = (lo, hi)
        self.min_samples = max(3, self.window // 4 if min_samples is None else int(min_samples))
        self.min_sensitivity = float(min_sensitivity)
        self.correlation_samples = float(correlation_samples)
        self.update_every = max(1, int(update_every))
        self._grid = np.linspace(lo, hi, int(grid_points))
        self._coef = np.zeros((6, self.window))
        self._ok = np.zeros(self.window, dtype=bool)
        self._pending: list[tuple] = []
        self._i = 0
        self._n_updates = 0
        self._last = HEstimate(np.nan, np.nan, np.nan, 0, np.nan)
        self._h_prev = float("nan")   # last Gauss-Newton minimum (NaN: search the grid next time)
        self._since_grid = 0

    def reset(self) -> None:
        """Forget all samples."""
        self._ok[:] = False
        self._pending = []
        self._i = 0
        self._n_updates = 0
        self._last = HEstimate(np.nan, np.nan, np.nan, 0, np.nan)
        self._h_prev = float("nan")
        self._since_grid = 0

    def update(self, gamma: float, phi: float, gamma_dot: float, phi_dot: float, x_ddot: float,
               gamma_ddot: float, phi_ddot: float) -> HEstimate:
        """Add one sample (SI units, radians) and return the current estimate.

        A sample with any non-finite state is not used (but ages the window).

        Parameters
        ----------
        gamma, phi : float
            EUC body pitch and rider pitch about the ankle hinge [rad].
        gamma_dot, phi_dot : float
            Pitch rates [rad/s].
        x_ddot : float
            Longitudinal acceleration of the wheel centre [m/s^2].
        gamma_ddot, phi_ddot : float
            Pitch accelerations [rad/s^2].

        Returns
        -------
        HEstimate
            The latest estimate (refreshed every ``update_every`` samples).
        """
        j = self._i
        # the sample's coefficients are computed with the others pending, in one vectorized call, when the
        # estimate is next needed (what one sample costs alone is mostly numpy's per-call overhead)
        self._pending.append((j, gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot))
        self._ok[j] = False
        self._i = (j + 1) % self.window
        self._n_updates += 1
        if len(self._pending) >= self.window:
            self._flush()
        if self._n_updates % self.update_every == 0:
            self._last = self._estimate()
        return self._last

    def _flush(self) -> None:
        """Store the coefficients of the pending samples (a later sample in the same slot wins)."""
        if not self._pending:
            return
        rows = np.array(self._pending, dtype=float)
        self._pending = []
        j = rows[:, 0].astype(np.int64)
        c = residual_coefficients(tuple(rows[:, 1:].T), self.params, self.model)
        ok = np.all(np.isfinite(c), axis=0)
        self._coef[:, j] = np.where(ok, c, 0.0)
        self._ok[j] = ok

    @property
    def estimate(self) -> HEstimate:
        """The latest estimate."""
        return self._last

    def status(self, dt: float, est: HEstimate | None = None) -> str:
        """What the estimate is, in words: ``"ok"`` or ``"not yet (...)"`` with the reason.

        Parameters
        ----------
        dt : float
            Sample period [s] (to state the time still needed).
        est : HEstimate, optional
            The estimate to describe (default: the latest).

        Returns
        -------
        str
            ``"ok"`` or ``"not yet (...)"``.

        Examples
        --------
        >>> from euc_ros.core.model.terms import EucParams
        >>> from euc_ros.core.session import default_session
        >>> e = OnlineHEstimator(EucParams.from_session(default_session()), window=1200)
        >>> e.status(1 / 120)
        'not yet (0.0 of 2.5 s of valid states)'
        """
        est = self._last if est is None else est
        if np.isfinite(est.h_m):
            return "ok"
        if est.n_samples < self.min_samples:
            return f"not yet ({est.n_samples * dt:.1f} of {self.min_samples * dt:.1f} s of valid states)"
        return (f"not yet (too little excitation: sensitivity {est.sensitivity_nm_per_m:.1f} < "
                f"{self.min_sensitivity:g} N m/m)")

    def refresh(self) -> HEstimate:
        """Re-estimate now from the samples held (whatever ``update_every`` says) and return it.

        Returns
        -------
        HEstimate
            The new estimate.
        """
        self._last = self._estimate()
        return self._last

    def _residual(self, coef: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        c, a0, a1, a2, d0, d1 = coef
        N = a0 + h * (a1 + h * a2)
        D = d0 + d1 * h
        e = c * N / D
        de = c * ((a1 + 2 * a2 * h) * D - N * d1) / D**2
        return e, de

    def _grid_start(self, coef: np.ndarray) -> float:
        """The coarse grid's minimum of S(h), on an evenly spread subset of at most GRID_SAMPLES samples.

        It only picks the basin; a smooth function of h is located as well by the subset.
        """
        stride = max(1, coef.shape[1] // GRID_SAMPLES)
        c, a0, a1, a2, d0, d1 = coef[:, ::stride]
        H = self._grid[:, None]
        sse = np.sum((c * (a0 + H * (a1 + H * a2)) / (d0 + d1 * H)) ** 2, axis=1)
        return float(self._grid[int(np.argmin(sse))])

    def _gauss_newton(self, coef: np.ndarray, h: float) -> tuple[float, np.ndarray, np.ndarray, bool]:
        """Gauss-Newton from ``h`` within the bounds: ``(h, e(h), e'(h), on_bound)``."""
        lo, hi = self.h_bounds
        for _ in range(8):
            e, de = self._residual(coef, h)
            jtj = _dot(de, de)
            if jtj <= 0:
                return h, e, de, False
            h_new = min(max(h - _dot(e, de) / jtj, lo), hi)
            if abs(h_new - h) < GN_TOL_M:
                break
            h = h_new
        else:
            e, de = self._residual(coef, h)
        return h, e, de, h <= lo or h >= hi

    def _estimate(self) -> HEstimate:
        self._flush()
        coef = self._coef[:, self._ok]
        n = coef.shape[1]
        if n < self.min_samples:
            self._h_prev = float("nan")
            return HEstimate(np.nan, np.nan, np.nan, n, np.nan)
        # Between grid searches, start from the previous minimum: one or two Gauss-Newton steps over the
        # window (~0.3 ms at 30 s x 360 Hz) instead of the grid and eight steps (~2.6 ms) at every update,
        # which delayed one frame in 36 at 360 Hz. The grid runs again periodically, and whenever
        # Gauss-Newton from the previous minimum ends on a bound, so a new basin is not missed for long.
        warm = np.isfinite(self._h_prev) and self._since_grid < REGRID_EVERY
        if warm:
            self._since_grid += 1
            h, e, de, on_bound = self._gauss_newton(coef, self._h_prev)
        if not warm or on_bound:
            self._since_grid = 0
            h, e, de, _ = self._gauss_newton(coef, self._grid_start(coef))
        self._h_prev = h
        sse_h = _dot(e, e)
        jtj = _dot(de, de)
        sens = float(np.sqrt(jtj / n))
        rmse = float(np.sqrt(sse_h / n))
        if sens < self.min_sensitivity or jtj <= 0:
            return HEstimate(np.nan, np.nan, rmse, n, sens)
        std = float(np.sqrt(self.correlation_samples * sse_h / max(n - 1, 1) / jtj))
        return HEstimate(h, std, rmse, n, sens)
