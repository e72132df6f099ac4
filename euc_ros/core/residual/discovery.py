"""Discovery: a sparse combination of physically typed basis forces for what no named effect explains.

After the named effects, the residual may still carry structure. The basis is built from measured
signals and applied at physical points, each column a generalized force derived by virtual power:

* points and directions: **x at the contact** (``dQ = [F, 0, 0]``), **x at the rider CoG** and **z at
  the rider CoG** (``dQ = J_G^T F``, J_G of the Appendix-A geometry), and a **torque on the rider's
  pitch** (``dQ = [0, 0, T]``): an x force at height l on the rider is the same force at the CoG plus
  the torque ``F (l - h) cos(phi)``. The residual sees a generalized force only through
  ``R dQ_x + dQ_gamma + dQ_phi`` (the directions orthogonal to b_d and b_h; measured on the force map to
  1e-15), i.e. a horizontal force at height z above the contact only through its moment ``z F`` about the
  contact: its point of application is not resolved, and a force at the hand is found as the force at the
  CoG with the same moment (a rope at d = 0.45 m above the hinge: ``k (R - l0 + d) / (R - l0 + h)``);
* functions (with units): ``1``, ``x_dot``, ``x_dot |x_dot|``, ``tanh(x_dot / 0.05)`` (a sign),
  ``sin(s/R)``, ``cos(s/R)`` (the wheel's rotation, s the path length), ``psi_dot x_dot``
  (lateral acceleration in turns), ``cos(psi)``, ``X cos(psi)``, ``sin(psi)``, ``Y sin(psi)`` (a force
  fixed in the lab, constant or growing with lab position, as the heading sees it), ``s`` (position
  along the path), ``t``, ``phi_dot``.

Not in the basis: the accelerations and the pitch angles themselves. The residual is linear in the
measured accelerations and angles, so terms in them (a mass, an inertia, a gravity torque) can cancel
the residual's own noise on held-out data too (measured: 4 such terms took a no-effect ride's held-out
RMSE from 0.34 to 0.03 N m, below its noise floor): those are the named parameter candidates' job.

Forces along the input directions (hinge torque, motor torque) cannot show in the residual and are not
in the basis. The terms are chosen by best-subset search (:func:`best_subsets`, on the residual's
sensitivity to each column with h projected out), the number of terms by held-out error over the
analysis' folds; the selection is repeated around the h the chosen terms imply when they move it
(:func:`euc_ros.core.residual.discovery.discover_terms`); the chosen terms are then fitted jointly with h
(:class:`DiscoveredEffect`) like any candidate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations
from typing import Sequence

import numpy as np

from euc_ros.core.model.effects import Candidate, ParamInfo, jacobian_G
from euc_ros.core.residual.selection import H_BOUNDS, HeldOut, Model, fit_model, held_out
from euc_ros.core.residual.significance import AMBIGUITY_ALPHA, paired_block_test
from euc_ros.core.states.contexts import Recording

#: Most terms a discovered model may have.
MAX_TERMS = 4
#: Speed scale of the sign function [m/s].
SIGN_SPEED = 0.05

#: (name, unit) of the functions, in basis order.
FUNCTIONS = (("1", "1"), ("x_dot", "m/s"), ("x_dot|x_dot|", "m^2/s^2"), ("tanh(x_dot/0.05)", "1"),
             ("sin(s/R)", "1"), ("cos(s/R)", "1"), ("psi_dot x_dot", "m/s^2"),
             ("cos(psi)", "1"), ("X cos(psi)", "m"), ("sin(psi)", "1"), ("Y sin(psi)", "m"), ("s", "m"), ("t", "s"),
             ("phi_dot", "rad/s"))
#: (coordinate, point) of the forces' directions and points of application.
POINTS = (("x", "contact"), ("x", "rider CoG"), ("z", "rider CoG"), ("pitch", "rider"))
#: Unit of each point's generalized force: a force [N], or a torque on the rider's pitch [N m] (with a force
#: at the CoG, it moves the force's point of application up or down the rider: a hand, a shoulder).
POINT_UNITS = ("N", "N", "N", "N m")


def _where(point: int) -> str:
    coord, at = POINTS[point]
    return f"{coord} at the {at}"


def feature_matrix(ctx) -> np.ndarray:
    """The functions of :data:`FUNCTIONS` for one context (n, len(FUNCTIONS))."""
    p = ctx.p()
    s = ctx.extras.get("path_s")
    if s is None:
        s = np.concatenate([[0.0], np.cumsum(0.5 * (ctx.x_dot[1:] + ctx.x_dot[:-1]) * np.diff(ctx.t))])
    X = ctx.extras.get("lab_x", np.zeros_like(ctx.t))
    Y = ctx.extras.get("lab_y", np.zeros_like(ctx.t))
    R = float(np.mean(p.R))
    v = ctx.x_dot
    c, sn = np.cos(ctx.psi), np.sin(ctx.psi)
    cols = [np.ones_like(v), v, v * np.abs(v), np.tanh(v / SIGN_SPEED), np.sin(s / R), np.cos(s / R),
            ctx.psi_dot * v, c, X * c, sn, Y * sn, s, ctx.t, ctx.phi_dot]
    return np.stack(cols, axis=1)


def basis_forces(ctx, columns) -> np.ndarray:
    """Generalized forces (n, 3) of a combination: ``columns`` = list of (point index, function index, coef)."""
    F = feature_matrix(ctx)
    n = ctx.t.shape[0]
    dQ = np.zeros((n, 3))
    jx = jz = None
    for point, func, coef in columns:
        f = coef * F[:, func]
        if point == 0:
            dQ[:, 0] += f
        elif point == 3:
            dQ[:, 2] += f
        else:
            if jx is None:
                jx, jz = jacobian_G(ctx, ctx.p())
            dQ += (jx if point == 1 else jz) * f[:, None]
    return dQ


@dataclass(frozen=True)
class Term:
    """One discovered term: function ``func`` times a coefficient, acting at ``point``."""

    point: int
    func: int

    @property
    def label(self) -> str:
        return f"{FUNCTIONS[self.func][0]} on {_where(self.point)}"

    def coef_unit(self) -> str:
        fu = FUNCTIONS[self.func][1]
        pu = POINT_UNITS[self.point]
        return pu if fu == "1" else f"{pu}/({fu})"

    def formula(self, coef: float) -> str:
        f = FUNCTIONS[self.func][0]
        factor = "" if f == "1" else f" {f}"
        return f"{coef:+.4g}{factor} {POINT_UNITS[self.point]} on {_where(self.point)}"


class DiscoveredEffect(Candidate):
    """A discovered combination of basis terms, fitted like a named candidate (coefficients free)."""

    name = "discovered"

    def __init__(self, terms: list[Term], scales: list[float], start=None):
        self.terms = list(terms)
        self._start = np.zeros(len(terms)) if start is None else np.asarray(start, float)
        self.params = tuple(ParamInfo(f"c{k}_{t.label}", t.coef_unit(), -1e6, 1e6, 0.0, max(sc, 1e-9))
                            for k, (t, sc) in enumerate(zip(terms, scales)))

    def starts(self):
        return [self._start.copy()]

    def force(self, ctx, theta):
        return basis_forces(ctx, [(t.point, t.func, c) for t, c in zip(self.terms, theta)])

    def report(self, theta):
        return {f"discovered_{k + 1}": float(c) for k, c in enumerate(theta)}

    def describe(self, theta) -> list[dict]:
        """JSON rows: name, formula with units, point, coordinate, parameter."""
        out = []
        for k, (t, c) in enumerate(zip(self.terms, theta)):
            coord, point = POINTS[t.point]
            out.append({"name": f"discovered_{k + 1}", "formula": t.formula(float(c)), "function": FUNCTIONS[t.func][0],
                        "function_unit": FUNCTIONS[t.func][1], "point": point, "coordinate": coord,
                        "coefficient": float(c), "coefficient_unit": t.coef_unit()})
        return out


def all_terms() -> list[Term]:
    """Every (point, function) term, point-major (the column order of :func:`basis_sensitivities`)."""
    return [Term(p, f) for p in range(len(POINTS)) for f in range(len(FUNCTIONS))]


def basis_sensitivities(ctx, force_map: np.ndarray) -> np.ndarray:
    """Change of the residual per unit coefficient of every term of :func:`all_terms` (n, k).

    ``force_map`` (n, 3): the residual's change per unit extra generalized force along each coordinate
    (the residual is linear in an extra force), so a term's column is ``force_map . dQ_term``.
    """
    F = feature_matrix(ctx)
    jx, jz = jacobian_G(ctx, ctx.p())
    gains = (force_map[:, 0], np.sum(force_map * jx, axis=1), np.sum(force_map * jz, axis=1), force_map[:, 2])
    return np.concatenate([g[:, None] * F for g in gains], axis=1)


def forward_select(r0: np.ndarray, B: np.ndarray, max_terms: int = MAX_TERMS) -> list[list[int]]:
    """Orthogonal matching pursuit: the column sets of 1..max_terms terms minimising ||r0 + B c||."""
    norms = np.linalg.norm(B, axis=0)
    usable = norms > 1e-12 * (norms.max() if norms.size else 1.0)
    chosen: list[int] = []
    out = []
    resid = r0.copy()
    for _ in range(max_terms):
        score = np.where(usable, np.abs(B.T @ resid) / np.where(usable, norms, 1.0), -np.inf)
        score[chosen] = -np.inf
        k = int(np.argmax(score))
        if not np.isfinite(score[k]):
            break
        chosen.append(k)
        c, *_ = np.linalg.lstsq(B[:, chosen], -r0, rcond=None)
        resid = r0 + B[:, chosen] @ c
        out.append(list(chosen))
    return out


#: Term sets up to this size are searched exhaustively (:func:`best_subsets`; pairs: a force at a point of the
#: rider is a CoG force plus a pitch torque); larger ones grow greedily (triples cost 20x more).
EXHAUSTIVE_TERMS = 2
#: Subsets whose normalised Gram matrix has a determinant below this are near-collinear and skipped.
MIN_GRAM_DET = 1e-8


def best_subsets(r0: np.ndarray, B: np.ndarray, max_terms: int = MAX_TERMS) -> list[list[int]]:
    """Column sets of 1..max_terms terms minimising ``||r0 + B c||``: the best single and pair by exhaustive
    search (:data:`EXHAUSTIVE_TERMS`), larger sets by greedy extension of the best pair.

    Greedy selection (:func:`forward_select`) can miss a force that needs two terms together (a force at a
    hand = the same force at the CoG plus a pitch torque, each alone a poor fit). The search works on the
    normalised Gram matrix ``G = Bn^T Bn`` and ``b = Bn^T r0``: a set S removes ``b_S^T G_S^-1 b_S`` of the
    squared residual; near-collinear sets (``det G_S`` below :data:`MIN_GRAM_DET`) are skipped.
    """
    norms = np.linalg.norm(B, axis=0)
    usable = np.flatnonzero(norms > 1e-12 * (norms.max() if norms.size else 1.0))
    if usable.size == 0:
        return []
    Bn = B[:, usable] / norms[usable]
    G = Bn.T @ Bn
    b = Bn.T @ r0
    out: list[list[int]] = []
    for k in range(1, min(EXHAUSTIVE_TERMS, max_terms, usable.size) + 1):
        sets = np.array(list(combinations(range(usable.size), k)))
        Gs = G[sets[:, :, None], sets[:, None, :]]
        bs = b[sets]
        det = np.linalg.det(Gs)
        ok = det > MIN_GRAM_DET
        if not ok.any():
            break
        gain = np.full(sets.shape[0], -np.inf)
        sol = np.linalg.solve(Gs[ok], bs[ok][:, :, None])[:, :, 0]
        gain[ok] = np.sum(bs[ok] * sol, axis=1)
        out.append([int(usable[j]) for j in sets[int(np.argmax(gain))]])
    if len(out) < max_terms and out:
        # greedy extension of the best exhaustive set
        chosen = list(out[-1])
        for _ in range(max_terms - len(out)):
            c, *_ = np.linalg.lstsq(B[:, chosen], -r0, rcond=None)
            resid = r0 + B[:, chosen] @ c
            score = np.full(B.shape[1], -np.inf)
            score[usable] = np.abs(B[:, usable].T @ resid) / norms[usable]
            score[chosen] = -np.inf
            k = int(np.argmax(score))
            if not np.isfinite(score[k]):
                break
            chosen.append(k)
            out.append(list(chosen))
    return out


def force_map(model: Model, recs: Sequence[Recording], x: np.ndarray) -> list[np.ndarray]:
    """Per recording, the change of the residual per unit extra generalized force along x, gamma and phi
    (n, 3): the residual is linear in an extra force (``-R m11 (w . dQ) / D``), so three evaluations give
    the sensitivity of any force."""
    out = []
    for r in recs:
        n = r.ctx.t.shape[0]
        r0 = model.residual(r, x)[0]
        cols = []
        for j in range(3):
            e = np.zeros((n, 3))
            e[:, j] = 1.0
            cols.append(model.residual(r, x, e)[0] - r0)
        out.append(np.stack(cols, axis=1))
    return out


#: Most re-linearisations of the discovery around the h its terms imply (Gauss-Newton on the joint fit).
DISCOVERY_RELINEARISE = 3


#: A change of h [m] below which the discovery's linearisation is kept.
DISCOVERY_H_STEP_M = 1e-3


def discover_terms(current: Model, current_x: np.ndarray, recs: Sequence[Recording], folds, h0: float,
                   current_ho: HeldOut, h_geometric: float = float("nan")) -> dict:
    """The discovery step (:mod:`euc_ros.core.residual.discovery`): terms by best-subset selection within each
    fold's training data, their number by held-out error, then the chosen terms fitted jointly with h.

    The residual is linear in the terms' coefficients but not in h (the rider's inertia m h^2): the selection
    works on the residual linearised in h. When the effect to discover biased the current model's h far from
    the truth (a rope: 0.26-0.33 m against 0.61), that linearisation is poor and spare terms make up for the
    missing curvature in h. So the selection is also made linearised at the segments' geometric h
    (``h_geometric``, measured, the same the admissibility test uses) and then around the h the chosen terms
    imply (re-linearised at the h of the full fit, at most :data:`DISCOVERY_RELINEARISE` times while h moves
    by more than :data:`DISCOVERY_H_STEP_M`; h is refitted within each fold's training data at every
    linearisation but the first). The discovered models of the linearisations are compared by their held-out
    error after the full (non-linear) fit: a tie (paired block test at :data:`AMBIGUITY_ALPHA`) goes to the
    one with fewer terms. The first linearisation is the current model's own, so a ride where no other
    fits better held-out is unchanged.

    Returns ``{"model", "x", "heldout", "info"}`` (model None when no number of terms beats none).
    """

    terms = all_terms()

    def with_h(r0, B, hc):
        # h is always in the model: the terms are chosen for, and fitted with, the h column projected out
        u = hc / max(np.linalg.norm(hc), 1e-300)
        return r0 - u * (u @ r0), B - np.outer(u, u @ B)

    def select(h_lin: float | None):
        # h_lin None: linearised at the current model's fit (in each fold its own h); else at h_lin, with h
        # refitted within each fold's training data (also without terms)
        x_lin = np.array(current_x, float)
        if h_lin is not None:
            x_lin[0] = h_lin
        L = force_map(current, recs, x_lin)
        B_all = [basis_sensitivities(r.ctx, Li) for r, Li in zip(recs, L)]
        base = [current.residual(r, x_lin) for r in recs]
        dh = 1e-3
        x1 = x_lin.copy()
        x1[0] += dh
        hcol = [(current.residual(r, x1)[0] - b[0]) / dh for r, b in zip(recs, base)]
        per_k: dict[int, list[np.ndarray]] = {}
        for fold, x_fold in zip(folds, current_ho.params):
            x_fold = np.array(x_fold, float)
            if h_lin is not None:
                x_fold[0] = h_lin
            fres = [current.residual(r, x_fold) if np.any(te) or np.any(tr) else None
                    for r, tr, te in zip(recs, fold.train, fold.test)]
            tr_rows = [np.asarray(tr, bool) & f[1] for tr, f in zip(fold.train, fres) if f is not None]
            idx = [i for i, f in enumerate(fres) if f is not None]
            r0 = np.concatenate([fres[i][0][rw] for i, rw in zip(idx, tr_rows)])
            B = np.concatenate([B_all[i][rw] for i, rw in zip(idx, tr_rows)])
            hc = np.concatenate([hcol[i][rw] for i, rw in zip(idx, tr_rows)])
            sets = best_subsets(*with_h(r0, B, hc))
            te_rows = [(i, np.asarray(fold.test[i], bool) & fres[i][1]) for i in idx if np.any(fold.test[i])]
            r0t = np.concatenate([fres[i][0][rw] for i, rw in te_rows])
            Bt = np.concatenate([B_all[i][rw] for i, rw in te_rows])
            hct = np.concatenate([hcol[i][rw] for i, rw in te_rows])
            if h_lin is None:
                per_k.setdefault(0, []).append(r0t)
            else:
                c0 = -(hc @ r0) / max(hc @ hc, 1e-300)
                per_k.setdefault(0, []).append(r0t + hct * c0)
            for k, cols in enumerate(sets, start=1):
                A = np.column_stack([hc, B[:, cols]])
                c, *_ = np.linalg.lstsq(A, -r0, rcond=None)
                per_k.setdefault(k, []).append(r0t + np.column_stack([hct, Bt[:, cols]]) @ c)
        complete = {k: np.concatenate(v) for k, v in per_k.items() if len(v) == len(folds)}
        rmse = {k: float(np.sqrt(np.mean(v ** 2))) for k, v in complete.items()}
        best_k = min(rmse, key=lambda k: (rmse[k], k))
        # the fewest terms within 2 % of the best held-out error (parsimony)
        best_k = min(k for k in rmse if rmse[k] <= 1.02 * rmse[best_k])
        if best_k == 0:
            return rmse, 0, complete, None, None, 0.0
        rows = [b[1] for b in base]
        r0 = np.concatenate([b[0][m] for b, m in zip(base, rows)])
        B = np.concatenate([Bi[m] for Bi, m in zip(B_all, rows)])
        hc = np.concatenate([h[m] for h, m in zip(hcol, rows)])
        cols = best_subsets(*with_h(r0, B, hc), best_k)[-1]
        c, *_ = np.linalg.lstsq(np.column_stack([hc, B[:, cols]]), -r0, rcond=None)
        return rmse, best_k, complete, cols, c[1:], float(c[0])

    def finalize(sel, h_lin):
        """The chosen terms fitted jointly with h and all parameters, and their held-out residual."""
        rmse, best_k, complete, cols, c, dhh = sel
        if best_k == 0:
            return None
        eff = DiscoveredEffect([terms[j] for j in cols], [max(abs(v), 1e-6) for v in c], start=c)
        model = Model(current.effects + [eff])
        start = np.concatenate([current_x, c])
        start[0] = float(np.clip(h_lin + dhh, *H_BOUNDS))
        full = fit_model(model, recs, h0, start=start)
        return {"model": model, "x": full.x, "heldout": held_out(model, recs, h0, folds, start=full.x),
                "sel": sel, "h_lin": h_lin, "k": best_k}

    def preferred(a, b):
        """The better of two discovered models by held-out error; a tie (the better not significantly better,
        paired block test at AMBIGUITY_ALPHA) goes to the one with fewer terms."""
        if a is None or b is None:
            return a if b is None else b
        lo, hi = (a, b) if a["heldout"].rmse <= b["heldout"].rmse else (b, a)
        if hi["k"] < lo["k"] and paired_block_test(hi["heldout"], lo["heldout"]) >= AMBIGUITY_ALPHA:
            return hi
        return lo

    h_cur = float(current_x[0])
    first = select(None)
    best = finalize(first, h_cur)
    h_path = [h_cur]
    if math.isfinite(h_geometric) and abs(h_geometric - h_cur) > DISCOVERY_H_STEP_M:
        h_g = float(np.clip(h_geometric, *H_BOUNDS))
        h_path.append(h_g)
        best = preferred(best, finalize(select(h_g), h_g))
    for _ in range(DISCOVERY_RELINEARISE):
        if best is None:
            break
        h_fit = float(np.clip(best["x"][0], *H_BOUNDS))
        if abs(h_fit - best["h_lin"]) < DISCOVERY_H_STEP_M:
            break
        h_path.append(h_fit)
        nxt = preferred(best, finalize(select(h_fit), h_fit))
        if nxt is best:
            break
        best = nxt
    sel = first if best is None else best["sel"]
    rmse, best_k, complete = sel[0], sel[1], sel[2]
    info = {"run": True, "heldout_rmse_by_terms": [rmse[k] for k in sorted(rmse)], "terms": best_k,
            "linearised_at_h_m": h_cur if best is None else best["h_lin"], "linearisations_tried_h_m": h_path}
    if best is None:
        return {"model": None, "x": None, "heldout": None, "info": info}
    # the held-out residual of the terms chosen within each fold (no leakage of the selection into the test)
    if complete[best_k].shape == current_ho.residual.shape:
        info["selection_heldout"] = HeldOut(current, complete[best_k], current_ho.block, [], current_ho.index)
    return {"model": best["model"], "x": best["x"], "heldout": best["heldout"], "info": info}
