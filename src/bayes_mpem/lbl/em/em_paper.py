"""The paper's EM for one beacon, as written (eqs. 3-10).

:func:`fit_paper_em` follows the paper's algorithm: chi-square tail
probabilities in the E-step (:func:`paper_e_step`) with the ``Pol`` rule for
outliers and equal priors, then (:func:`paper_m_step`) the gamma_MP-weighted
average of the per-range plane heights of eq. 8, blended with the previous
one by ``alpha`` (eq. 10), and eq. 9 (as a variance) for the multipath
scatter. It maximises no likelihood, so it reports none. Every
interpretation is listed in ``docs/paper-em.md``.

The maximum-likelihood alternative (the package's default) is
:mod:`bayes_mpem.lbl.em.em_mixture`; both return an
:class:`~bayes_mpem.lbl.em.em_result.EMResult`.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import special

from ..._validate import check_finite, check_positive
from ...exceptions import ConvergenceWarning
from ...io.survey import BeaconData
from ...mixture.densities import CLASSES
from ..model import geometry
from ..model.beacon_geometry import BeaconGeometry
from .em_result import (
    EMResult,
    check_max_iter,
    check_options,
    estimate_sigma_dp,
    mean_resp_history,
    wdot,
    with_flags,
)

# --------------------------------------------------------------------------
# the paper's EM (eqs. 3-10)


def paper_e_step(geom: BeaconGeometry, d0, sigma_mp, sigma_dp, pol, path="triangle"):
    """E-step of the paper (eqs. 3-6 and the ``Pol`` rule).

    ``P(z|j) = 1 - chi2.cdf(u, 1)`` with ``u = (z - z_hat_j)^2 / sigma_j^2``
    for j = DP, MP (computed as ``erfc(sqrt(u / 2))``); ``P(z|OL) = Pol``
    unless ``1 - P(z|DP) - P(z|MP) < Pol``, then that difference clipped at 0.
    Priors are equal and cancel.

    Parameters
    ----------
    geom : BeaconGeometry
    d0, sigma_mp, sigma_dp : float
    pol : float
        Outlier threshold in (0, 1).
    path : {"triangle", "double"}

    Returns
    -------
    numpy.ndarray
        ``(n, 3)`` class probabilities.
    """
    p_dp = special.erfc(np.abs(geom.z - geom.direct) / (np.sqrt(2.0) * sigma_dp))
    p_mp = special.erfc(np.abs(geom.z - geom.multipath(d0, path)) / (np.sqrt(2.0) * sigma_mp))
    # flush subnormal tail probabilities (< 1e-300) to 0: numerically nil, and they would
    # slow every later product by ~100x
    p_dp[p_dp < 1e-300] = 0.0
    p_mp[p_mp < 1e-300] = 0.0
    rest = 1.0 - p_dp - p_mp
    p_ol = np.where(rest < pol, np.clip(rest, 0.0, None), pol)
    resp = np.stack([p_dp, p_mp, p_ol], axis=1)
    return resp / resp.sum(axis=1, keepdims=True)


def paper_m_step(geom: BeaconGeometry, gamma_mp, d0_prev, alpha, path="triangle", *, d0k=None):
    """M-step of the paper (eqs. 8, 10 and 9).

    Parameters
    ----------
    geom : BeaconGeometry
    gamma_mp : numpy.ndarray
        Multipath probabilities from the E-step.
    d0_prev : float
        Plane height of the previous iteration.
    alpha : float
        Blending factor of eq. 10.
    path : {"triangle", "double"}
    d0k : numpy.ndarray, optional
        Precomputed per-range plane heights
        (:func:`~bayes_mpem.lbl.model.geometry.invert_plane_height`); they do not depend
        on the parameters, so the EM loop computes them once.

    Returns
    -------
    d0, sigma_mp : float
        ``d0`` is the gamma_MP-weighted mean of the per-range ``d0(k)`` (ranges
        with no real inversion are left out), blended with ``d0_prev``;
        ``sigma_mp`` is the square root of the weighted mean squared
        multipath residual at that ``d0``.
    """
    if d0k is None:
        d0k = geometry.invert_plane_height(geom.z, geom.h, geom.dz, path, direct=geom.direct)
    ok = np.isfinite(d0k)
    wsum = gamma_mp[ok].sum()
    d0_avg = float(wdot(gamma_mp[ok], d0k[ok]) / wsum) if wsum > 0 else d0_prev
    d0 = (1.0 - alpha) * d0_prev + alpha * d0_avg
    res2 = (geom.z - geom.multipath(d0, path)) ** 2
    g = gamma_mp.sum()
    var = float(wdot(gamma_mp, res2) / g) if g > 0 else float("nan")
    return d0, float(np.sqrt(var))


def _run_paper(geom, d0, s_mp, s_dp, pol, alpha, path, *, tol, max_iter):
    """Run the paper's iterations from ``(d0, s_mp)``.

    Returns ``(d0, sigma_mp, resp, first_resp, history, n_iter, converged)``.
    """
    d0k = geometry.invert_plane_height(geom.z, geom.h, geom.dz, path, direct=geom.direct)
    hist = {k: [] for k in ("d0", "sigma_mp", "sigma_dp", "p_dp", "p_mp", "p_ol")}

    def record(resp):
        hist["d0"].append(d0)
        hist["sigma_mp"].append(s_mp)
        hist["sigma_dp"].append(s_dp)
        for c, m in zip(CLASSES, mean_resp_history(resp), strict=True):
            hist["p_" + c].append(float(m))

    resp = paper_e_step(geom, d0, s_mp, s_dp, pol, path)
    first_resp = resp
    record(resp)  # state 0: the initial parameters and the first classification
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        d0_new, s_new = paper_m_step(geom, resp[:, 1], d0, alpha, path, d0k=d0k)
        done = abs(d0_new - d0) < tol and abs(s_new - s_mp) < tol
        d0, s_mp = d0_new, s_new
        if not np.isfinite(s_mp) or s_mp <= 0:
            break  # sigma_MP collapsed: the probabilities stay those of the last E-step
        resp = paper_e_step(geom, d0, s_mp, s_dp, pol, path)
        record(resp)
        if done:
            converged = True
            break
    return d0, s_mp, resp, first_resp, hist, it, converged


def fit_paper_em(
    data: BeaconData,
    *,
    pol: float = 0.05,
    alpha: float = 0.5,
    sigma_dp: float | None = None,
    path: str = "triangle",
    d0_init: float = 4000.0,
    sigma_mp2_init: float = 1e7,
    tol: float = 1e-3,
    max_iter: int = 2000,
) -> EMResult:
    """Fit one beacon with the paper's EM, as written (eqs. 3-10).

    Parameters
    ----------
    data : BeaconData
        Replies of one beacon.
    pol : float, default 0.05
        Outlier threshold ``Pol`` in (0, 1).
    alpha : float, default 0.5
        Convergence factor of eq. 10, in (0, 1].
    sigma_dp : float, optional
        Direct-path scatter (m). The paper takes it as known (3.97 m for
        ABE58); if omitted it is estimated robustly from the ranges near the
        direct path (:func:`estimate_sigma_dp`).
    path : {"triangle", "double"}
    d0_init : float, default 4000
        Initial plane height (m), the paper's value.
    sigma_mp2_init : float, default 1e7
        Initial multipath variance (m^2), the paper's value.
    tol : float, default 1e-3
        Stop when both ``d0`` and ``sigma_mp`` change by less than ``tol`` m.
    max_iter : int, default 2000

    Returns
    -------
    EMResult

    Warns
    -----
    ConvergenceWarning
        When ``max_iter`` is reached first.
    FitQualityWarning
        When the result is not a credible reflector (:func:`quality_flags`).

    Examples
    --------
    >>> from bayes_mpem.lbl.simulation.simulate import simulate_survey
    >>> from bayes_mpem.lbl.em.em_paper import fit_paper_em
    >>> sim = simulate_survey("abe58", rng=1)
    >>> res = fit_paper_em(sim.survey.for_beacon("4"), sigma_dp=3.97)
    >>> abs(res.d0 - 2472) < 10
    True
    """
    fixed_dp = check_options(path=path, pol=pol, alpha=alpha, sigma_dp=sigma_dp)
    check_positive("sigma_mp2_init", sigma_mp2_init)
    check_positive("tol", tol)
    check_max_iter(max_iter)
    check_finite("d0_init", d0_init)
    geom = BeaconGeometry.from_data(data)
    s_dp = fixed_dp or estimate_sigma_dp(geom)
    d0, s_mp, resp, first_resp, hist, it, converged = _run_paper(
        geom, float(d0_init), float(np.sqrt(sigma_mp2_init)), s_dp, pol, alpha, path,
        tol=tol, max_iter=max_iter)
    if not converged:
        warnings.warn(
            f"beacon {data.beacon}: the paper's EM did not converge in {it} iterations "
            f"(d0={d0:.2f} m, sigma_mp={s_mp:.3g} m"
            + (", sigma_MP collapsed to 0)" if not s_mp > 0 else ")"),
            ConvergenceWarning,
            stacklevel=2,
        )
    mean = mean_resp_history(resp)
    return with_flags(EMResult(
        beacon=data.beacon,
        method="paper",
        path=path,
        d0=float(d0),
        sigma_mp=float(s_mp),
        sigma_dp=float(s_dp),
        weights={c: float(m) for c, m in zip(CLASSES, mean, strict=True)},
        resp=resp,
        rows=np.asarray(data.rows),
        n_iter=it,
        converged=converged,
        loglik=None,
        history={k: np.asarray(v) for k, v in hist.items()},
        first_resp=first_resp,
        settings={"pol": float(pol), "alpha": float(alpha), "d0_init": float(d0_init),
                  "sigma_mp2_init": float(sigma_mp2_init), "tol": float(tol),
                  "sigma_dp_fixed": sigma_dp is not None},
    ), data, 0.0)
