"""Shrunken least squares for the discovery's fold fits.

A Gaussian prior on the family coefficients whose scale the data choose (empirical Bayes).

A flexible family fitted on part of the recordings is poorly determined where that part never went: a lab
field's spline pieces a held-out run visits first, a drift polynomial past its training half. Plain least
squares gives such directions any size (coefficients of thousands of newtons), and the held-out error of a
right family then exceeds that of no family. A zero-mean prior on the coefficients of the unit-norm columns,
``c ~ N(0, tau^2 I)``, shrinks exactly the directions the training data do not see, and leaves the
well-determined ones as least squares fits them.

The prior's precision ``alpha = 1 / tau^2`` and the noise precision ``beta`` are chosen by the evidence
(MacKay's fixed point, the marginal likelihood of the linear-Gaussian model). The residual's samples are
correlated within blocks, so the likelihood is tempered by ``n_eff / n`` (the blocks count as the
independent samples, as in :func:`~euc_ros.core.residual.families.group_path`): with every sample counted,
the evidence would trust the data ``n / n_eff`` times too much and shrink nothing.

Columns fitted always (h) carry no prior: they are projected out first.
"""
from __future__ import annotations

import numpy as np

#: Fixed-point iterations of the evidence and their relative tolerance on alpha.
EVIDENCE_ITERATIONS, EVIDENCE_TOL = 100, 1e-6


def evidence_ridge(B: np.ndarray, r: np.ndarray, n_eff: float | None = None,
                   norms: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Posterior-mean coefficients ``c`` of ``r ~ B c`` under ``c_j ~ N(0, tau^2 / |B_j|^2)``.

    That is the prior on the unit-norm columns, with ``tau`` from the tempered evidence (module docstring).

    Parameters
    ----------
    B : ndarray (n, m)
        Columns (any scale: the prior is set on the unit-norm columns).
    r : ndarray (n,)
        Data.
    n_eff : float, optional
        Effective number of independent samples (default n: no tempering).
    norms : ndarray (m,), optional
        The columns' scales the prior is set on (default their norms in ``B``).

    Returns
    -------
    (c, alpha_over_beta)
        Coefficients in the columns' own scale, and the ridge ratio ``alpha / (w beta)`` of the unit-norm
        problem (0: least squares).
    """
    B = np.asarray(B, float)
    r = np.asarray(r, float)
    n, m = B.shape
    c = np.zeros(m)
    nrm = np.linalg.norm(B, axis=0) if norms is None else np.asarray(norms, float)
    ok = (nrm > 0) & np.any(B != 0, axis=0)
    if n == 0 or not np.any(ok):
        return c, 0.0
    w = 1.0 if n_eff is None else float(np.clip(n_eff / n, 1e-9, 1.0))
    U, s, Vt = np.linalg.svd(B[:, ok] / nrm[ok], full_matrices=False)
    z = U.T @ r
    rss_out = max(float(r @ r - z @ z), 0.0)       # the part of r no column reaches
    s2 = s * s
    # start at least squares' noise and a prior as wide as the coefficients
    ls = np.where(s2 > 1e-300, z / np.where(s > 0, s, 1.0), 0.0)
    alpha = m / max(float(ls @ ls), 1e-300)
    beta = max(n - m, 1) / max(rss_out, 1e-300 * max(float(r @ r), 1e-300))
    for _ in range(EVIDENCE_ITERATIONS):
        lam = w * beta * s2
        d = w * beta * s / (alpha + lam)                 # posterior mean in the SVD basis: d * z
        mean = d * z
        gamma = float(np.sum(lam / (alpha + lam)))       # well-determined directions
        rss = rss_out + float(np.sum((z - s * mean) ** 2))
        alpha_new = gamma / max(float(mean @ mean), 1e-300)
        beta = max(w * n - gamma, 1e-9) / max(w * rss, 1e-300)
        done = abs(alpha_new - alpha) <= EVIDENCE_TOL * alpha
        alpha = alpha_new
        if done:
            break
    lam = w * beta * s2
    mean = (w * beta * s / (alpha + lam)) * z
    c[ok] = (Vt.T @ mean) / nrm[ok]
    return c, float(alpha / (w * beta))


def fit_with_free(free: np.ndarray, B: np.ndarray, r: np.ndarray, n_eff: float | None = None,
                  norms: np.ndarray | None = None) -> np.ndarray:
    """Coefficients ``[a, c]`` of ``r ~ free a + B c``: ``free`` (n,) without a prior, ``c`` by :func:`evidence_ridge`.

    ``free`` is projected out; ``c`` has the prior on the scale ``norms`` (default the columns' norms before the
    projection: a column nearly along ``free`` keeps a short remainder, whose coefficient the prior holds small instead
    of letting it grow as the remainder shrinks).

    Parameters
    ----------
    free : ndarray (n,)
        The column fitted without a prior (h's sensitivity).
    B : ndarray (n, m)
        The columns with the prior.
    r : ndarray (n,)
        Data.
    n_eff : float, optional
        Effective number of independent samples (default n: no tempering).
    norms : ndarray (m,), optional
        The columns' scales the prior is set on.

    Returns
    -------
    ndarray (m + 1,)
        ``[a, c...]`` (``a`` 0 when ``free`` is zero).
    """
    norms = np.linalg.norm(np.asarray(B, float), axis=0) if norms is None else np.asarray(norms, float)
    f = np.asarray(free, float)
    ff = float(f @ f)
    if ff <= 0:
        c, _ = evidence_ridge(B, r, n_eff, norms=norms)
        return np.concatenate([[0.0], c])
    u = f / np.sqrt(ff)
    rp = r - u * (u @ r)
    Bp = B - np.outer(u, u @ B)
    c, _ = evidence_ridge(Bp, rp, n_eff, norms=norms)
    a = float(f @ (r - B @ c)) / ff
    return np.concatenate([[a], c])
