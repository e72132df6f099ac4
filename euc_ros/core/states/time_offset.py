"""The time offset between the rider's bodies and the EUC's, measured from the pedals.

The feet stand on the pedals, so the shanks' pivots (the ankles) are fixed in the EUC body's frame
(:data:`~euc_ros.core.states.skeleton.DEFAULT_LINKS`: ``E -> LR``, ``E -> LL``). If the rider's bodies were
stamped ``dt`` late against the EUC's, an ankle would be seen where it was ``dt`` earlier, so in the EUC's
frame it would move against its fixed point by the ankle's velocity times ``dt``:
``R_E^T (p_b - p_E) = u - R_E^T v_b dt``. Regressing the link's deviation on ``R_E^T v_b`` measures ``dt``
directly, independent of the dynamics, as the contact path measures the floor. The residual's
``mocap_time_offset`` is then a name only near this measurement: a force that grows with speed shapes the
residual much as a time offset does, but it does not move the ankles on the pedals.

The standard error is a block jackknife over :data:`BLOCK_S` blocks (the link's soft-tissue sliding is
correlated over a fraction of a second). :data:`FLOOR_MS` bounds what the measurement cannot settle: an
ankle's soft tissue that slides with the speed.
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.rotations import quat_rotate
from euc_ros.core.states.link_sliding import link_deviation, usable_poses
from euc_ros.core.states.skeleton import DEFAULT_LINKS

#: Jackknife block length [s].
BLOCK_S = 1.0
#: Half-width floor of the plausible range around the measured offset [ms]: a shank marker cluster that
#: slides along the travel in proportion to speed by 1 mm at 1 m/s would read as 1 ms.
FLOOR_MS = 1.0
#: Standard errors of the measurement in the plausible range's half-width.
RANGE_SE = 3.0
#: Fewest usable frames of a recording for the measurement.
MIN_FRAMES = 32


def measure_time_offset(series_list, session, usable: list | None = None) -> dict | None:
    """The rider bodies' lag behind the EUC body [ms] from the ankles on the pedals (module docstring).

    Parameters
    ----------
    series_list : sequence of MocapSeries
        Recordings of one session (Z-up, SI).
    session : Session
    usable : list of ndarray, optional
        Per recording, :func:`~euc_ros.core.states.link_sliding.usable_poses` (default: made here).

    Returns
    -------
    dict or None
        ``dt_ms`` (positive: the rider's bodies are late, as :class:`~euc_ros.core.model.effects.MocapTimeOffset`
        counts it), ``se_ms``, ``plausible_ms`` (the range :data:`RANGE_SE` standard errors or
        :data:`FLOOR_MS` around it), ``links`` and ``frames`` used; None when no pedal link is recorded.
    """
    euc = session.euc.body
    names = set(session.segment_arrays()[0])
    links = [b for a, b in DEFAULT_LINKS if a == "E" and b in names]
    # per link, the sums of V . D and V . V over each of its blocks (the blocks are a link's own, numbered
    # on across links and recordings): no link's rows are kept once summed
    nums, dens, used = [], [], []
    frames = 0
    for k, s in enumerate(series_list):
        if euc not in s.bodies:
            continue
        usable_s = usable_poses(s) if usable is None else usable[k]
        dt = 1.0 / float(s.rate_hz)
        je = s.bodies.index(euc)
        for b in links:
            if b not in s.bodies:
                continue
            jb = s.bodies.index(b)
            d, both = link_deviation(s, euc, b, np.zeros(3), usable=usable_s)
            p = s.position[jb]
            v = np.full_like(p, np.nan)
            v[1:-1] = (p[2:] - p[:-2]) / (2.0 * dt)
            ok = both.copy()
            ok[1:-1] &= both[2:] & both[:-2]
            ok[[0, -1]] = False
            ok &= np.isfinite(v).all(1)
            if ok.sum() < MIN_FRAMES:
                continue
            # the ankle's velocity in the EUC's frame: R_E^T v (the conjugate quaternion rotates into it)
            ve = quat_rotate(s.quat[je][ok] * np.array([-1.0, -1.0, -1.0, 1.0]), v[ok])
            del v
            d = d[ok]
            t = s.t[ok] - s.t[0]
            blk = np.floor(t / BLOCK_S).astype(int)
            D = d - d.mean(0)
            V = ve - ve.mean(0)
            del d, ve
            nblk = int(blk.max()) + 1
            nums.append(np.bincount(blk, np.einsum("ni,ni->n", V, D), nblk))
            dens.append(np.bincount(blk, np.einsum("ni,ni->n", V, V), nblk))
            frames += int(D.shape[0])
            used.append(b)
    if not nums:
        return None
    # d = u - V dt (each recording's and link's own u removed by centring): dt = -(V . D) / (V . V)
    num = np.concatenate(nums)
    den = np.concatenate(dens)
    keep = den > 0
    if not keep.any() or den.sum() <= 0:
        return None
    est = -num.sum() / den.sum()
    num, den = num[keep], den[keep]
    B = num.size
    loo = -(num.sum() - num) / np.maximum(den.sum() - den, 1e-300)
    se = float(np.sqrt((B - 1) / B * np.sum((loo - loo.mean()) ** 2))) if B > 2 else float("inf")
    dt_ms, se_ms = 1e3 * float(est), 1e3 * se
    half = max(RANGE_SE * se_ms, FLOOR_MS)
    return {"dt_ms": dt_ms, "se_ms": se_ms, "plausible_ms": [dt_ms - half, dt_ms + half], "links": sorted(set(used)),
            "frames": frames}
