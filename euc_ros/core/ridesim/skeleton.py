"""Rider skeleton of the ride simulator: segment poses whose weighted CoG is exactly the true G.

The rider is built in the *lean frame* L (origin the ankle hinge A, axes Rz(psi) Rx(theta) Ry(phi):
x forward, y left, z along the lean axis). A crouched riding posture gives each rigid body of the EUC
paper's Table 2 a pivot (top of helmet, shoulder, elbow, wrist, hip, knee, ankle) and a fixed pitch
``beta_i`` of the segment relative to L (shanks forward, thighs back, forearms forward...). With the
session's mass fractions ``f_i`` and CoM offsets ``o_i`` (docs/session.md, rigid bodies) the
segment CoMs are ``c_i = p_i + Ry(beta_i) o_i`` in L.

To put the weighted CoG exactly at ``(0, 0, h)`` in L (distance h from A along the lean axis):

* the pivots' heights are scaled by ``s = (h - sum f_i (Ry(beta_i) o_i)_z) / sum f_i p_iz``, which is
  linear in h, so a time-varying h(t) gives a skeleton that stretches with it;
* all pivots except the ankles are shifted fore-aft and sideways by the constant that zeroes
  ``sum f_i c_ix`` and ``sum f_i c_iy``.

World poses are then ``pivot = A + R_L p_i``, orientation ``R_L Ry(beta_i)``, and
``sum f_i (pivot_i + R_i o_i) = A + R_L (0, 0, h) = G`` to rounding.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.session import Session

#: Base riding posture: body -> (pivot in the lean frame [m] before scaling, segment pitch beta [deg]).
#: A 1.75 m rider with flexed knees and a slightly forward trunk, hands low and forward.
BASE_POSTURE: dict[str, tuple[tuple[float, float, float], float]] = {
    "H": ((0.07, 0.0, 1.57), 10.0),
    "CHR": ((0.02, -0.18, 1.28), 10.0),
    "CHL": ((0.02, 0.18, 1.28), 10.0),
    "UAR": ((0.06, -0.21, 0.99), -8.0),
    "UAL": ((0.06, 0.21, 0.99), -8.0),
    "LAR": ((0.23, -0.20, 0.79), -40.0),
    "LAL": ((0.23, 0.20, 0.79), -40.0),
    "HR": ((-0.07, -0.10, 0.79), 0.0),
    "HL": ((-0.07, 0.10, 0.79), 0.0),
    "TR": ((0.11, -0.11, 0.41), -25.0),
    "TL": ((0.11, 0.11, 0.41), -25.0),
    "LR": ((0.0, -0.11, 0.0), 15.0),
    "LL": ((0.0, 0.11, 0.0), 15.0),
}
#: Bodies whose pivot is the ankle: they stay at the hinge height and are not shifted.
ANKLE_BODIES = ("LR", "LL")


def _ry(beta: np.ndarray) -> np.ndarray:
    c, s = np.cos(beta), np.sin(beta)
    z, o = np.zeros_like(beta), np.ones_like(beta)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


@dataclass(frozen=True)
class Skeleton:
    """Rider skeleton for a session's segment table.

    Parameters
    ----------
    bodies : list of str
        Segment bodies (session order).
    fractions : ndarray (b,)
        Mass fractions.
    offsets : ndarray (b, 3)
        CoM offsets from the pivot, body frame [m].
    base : ndarray (b, 3)
        Base pivots in the lean frame [m].
    rel_rot : ndarray (b, 3, 3)
        Segment orientation relative to the lean frame.
    shift : ndarray (b, 3)
        Fore-aft / lateral shift applied to every non-ankle pivot [m].
    """

    bodies: list[str]
    fractions: np.ndarray
    offsets: np.ndarray
    base: np.ndarray
    rel_rot: np.ndarray
    shift: np.ndarray

    @classmethod
    def for_session(cls, session: Session) -> "Skeleton":
        """Build the skeleton for the session's segments (bodies must be those of Table 2).

        Parameters
        ----------
        session : Session
            The session.

        Returns
        -------
        Skeleton
            The skeleton.

        Raises
        ------
        ConfigError
            Unknown segment bodies, or no mass above the ankles or the hinge.
        """
        names, fr, off = session.segment_arrays()
        unknown = [n for n in names if n not in BASE_POSTURE]
        if unknown:
            raise ConfigError(f"no skeleton pivot for segment bodies {unknown} (simulator knows "
                              f"{', '.join(BASE_POSTURE)})", path=session.source, key="rider.segments")
        base = np.array([BASE_POSTURE[n][0] for n in names], float)
        rel = _ry(np.radians([BASE_POSTURE[n][1] for n in names]))
        com_rel = np.einsum("bij,bj->bi", rel, off)
        movable = np.array([n not in ANKLE_BODIES for n in names])
        w = fr[movable].sum()
        if w <= 0:
            raise ConfigError("segment mass fractions leave no mass above the ankles", path=session.source,
                              key="rider.segments")
        lateral = fr @ (base + com_rel)
        shift = np.zeros_like(base)
        shift[movable, 0] = -lateral[0] / w
        shift[movable, 1] = -lateral[1] / w
        sk = cls(list(names), fr, off, base, rel, shift)
        if not sk._height_gain() > 0:
            raise ConfigError("segment table puts no mass above the hinge", path=session.source,
                              key="rider.segments")
        return sk

    def _height_gain(self) -> float:
        return float(self.fractions @ self.base[:, 2])

    def _com_rel_z(self) -> float:
        return float(self.fractions @ np.einsum("bij,bj->bi", self.rel_rot, self.offsets)[:, 2])

    def scale(self, h) -> np.ndarray:
        """Height scale of the pivots that puts the weighted CoG at height h [m] (array-friendly).

        Parameters
        ----------
        h : float or array_like
            CoG height(s) [m].

        Returns
        -------
        float or numpy.ndarray
            The scale(s).
        """
        return (np.asarray(h, float) - self._com_rel_z()) / self._height_gain()

    def pivots_lean(self, h) -> np.ndarray:
        """Pivots in the lean frame (b, ..., 3) for CoG height(s) h.

        Parameters
        ----------
        h : float or array_like
            CoG height(s) [m].

        Returns
        -------
        numpy.ndarray
            Pivots (b, ..., 3) [m].
        """
        s = self.scale(h)
        p = self.base + self.shift
        col = (-1,) + (1,) * s.ndim
        out = np.empty((p.shape[0],) + s.shape + (3,))
        out[..., 0] = p[:, 0].reshape(col)
        out[..., 1] = p[:, 1].reshape(col)
        out[..., 2] = p[:, 2].reshape(col) * s
        return out

    def poses(self, A: np.ndarray, R_lean: np.ndarray, h) -> tuple[np.ndarray, np.ndarray]:
        """World pivots (b, n, 3) and segment rotation matrices (b, n, 3, 3).

        Parameters
        ----------
        A : ndarray (n, 3)
            Ankle hinge positions [m].
        R_lean : ndarray (n, 3, 3)
            Lean-frame rotations ``Rz(psi) Rx(theta) Ry(phi)``.
        h : float or ndarray (n,)
            CoG height(s) [m].

        Returns
        -------
        pivots : numpy.ndarray
            World pivots (b, n, 3) [m].
        rotations : numpy.ndarray
            Rotations (b, n, 3, 3).
        """
        n = A.shape[0]
        p = self.pivots_lean(np.broadcast_to(np.asarray(h, float), (n,)))  # (b, n, 3)
        pos = A[None] + np.einsum("nij,bnj->bni", R_lean, p)
        rot = np.einsum("nij,bjk->bnik", R_lean, self.rel_rot)
        return pos, rot

    def cog(self, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """Weighted CoG (n, 3) of segment poses, as an analysis would reconstruct it.

        Parameters
        ----------
        pos : numpy.ndarray
            World pivots (b, n, 3) [m].
        rot : numpy.ndarray
            Rotations (b, n, 3, 3).

        Returns
        -------
        numpy.ndarray
            CoG (n, 3) [m].
        """
        com = pos + np.einsum("bnij,bj->bni", rot, self.offsets)
        return np.einsum("b,bni->ni", self.fractions, com)
