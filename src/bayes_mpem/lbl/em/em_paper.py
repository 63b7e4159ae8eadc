"""The paper's EM for one beacon, as written (eqs. 3-10; interpretations: docs/paper-em.md)."""

from __future__ import annotations

import warnings

import numpy as np
from scipy import special

from ..._validate import check_finite, check_int, check_positive
from ...exceptions import ConvergenceWarning
from ...io.survey import BeaconData
from ...mixture.densities import CLASSES
from ...mixture.em import EMModel, run_em
from ..model import geometry
from ..model.beacon_geometry import BeaconGeometry
from .em_result import (
    EMResult,
    check_fit_data,
    check_options,
    estimate_sigma_dp,
    mean_resp_history,
    options_as_input_errors,
    wdot,
    with_flags,
)

# --------------------------------------------------------------------------
# the paper's EM (eqs. 3-10)


def paper_e_step(geom: BeaconGeometry, d0, sigma_mp, sigma_dp, pol, path="triangle"):
    """E-step of the paper (eqs. 3-6 and the ``Pol`` rule; ``docs/paper-em.md``).

    Parameters
    ----------
    pol : float
        Outlier threshold in (0, 1).

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
    """M-step of the paper (eqs. 8, 10 and 9): the new ``(d0, sigma_mp)``.

    Parameters
    ----------
    gamma_mp : numpy.ndarray
        Multipath probabilities from the E-step.
    d0_prev : float
        Plane height of the previous iteration.
    alpha : float
        Blending factor of eq. 10.
    d0k : numpy.ndarray, optional
        The per-range plane heights, if computed.
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


#: A run "converged" while eq. 10's last undamped move (``d0_avg - d0``, the step over
#: ``alpha``) is more than this many ``tol`` is not converged: a tiny ``alpha`` shrinks every
#: step below ``tol`` from the start. At ``alpha >= 0.1`` the move is at most ``10 tol``.
STALL_FACTOR = 10.0


def _stalled(run, alpha, tol, beacon) -> bool:
    """Warn and return True where a tiny ``alpha`` stopped the run far from its fixed point."""
    d0 = run.history.get("d0", [])
    if len(d0) < 2:
        return False
    gap = abs(d0[-1] - d0[-2]) / alpha
    if gap <= STALL_FACTOR * tol:
        return False
    warnings.warn(f"beacon {beacon}: the paper's EM stopped after {run.n_iter} iterations "
                  f"because alpha={alpha:g} shrinks each step of d0 below tol={tol:g} m, while "
                  f"eq. 10's target d0 is still {gap:.3g} m away: not converged (d0={d0[-1]:.2f} "
                  "m); use a larger --alpha", ConvergenceWarning, stacklevel=3)
    return True


class _PaperEM(EMModel):
    """The paper's EM as an :class:`~bayes_mpem.mixture.em.EMModel` of ``(d0, sigma_mp)``."""

    def __init__(self, geom, s_dp, pol, alpha, path):
        self.geom, self.s_dp, self.pol, self.alpha, self.path = geom, s_dp, pol, alpha, path
        self.d0k = geometry.invert_plane_height(geom.z, geom.h, geom.dz, path, direct=geom.direct)

    def e_step(self, params):
        return None, paper_e_step(self.geom, *params, self.s_dp, self.pol, self.path)

    def m_step(self, params, resp):
        return paper_m_step(self.geom, resp[:, 1], params[0], self.alpha, self.path, d0k=self.d0k)

    def change(self, old, new, gain):
        return max(abs(new[0] - old[0]), abs(new[1] - old[1]))

    def usable(self, params):
        return bool(np.isfinite(params[1]) and params[1] > 0)  # else sigma_MP collapsed

    def record(self, params, loglik, resp):
        out = {"d0": params[0], "sigma_mp": params[1], "sigma_dp": self.s_dp}
        out.update(("p_" + c, float(m)) for c, m in zip(CLASSES, mean_resp_history(resp),
                                                          strict=True))
        return out


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
        Direct-path scatter (m), known in the paper (3.97 m for ABE58); estimated if omitted.
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

    Raises
    ------
    InputError
        ``data`` not a BeaconData (a Survey: ``survey.for_beacon(id)``), fewer than 3 ranges
        (as :func:`~bayes_mpem.lbl.em.em_mixture.fit_mixture_em`), or a bad option.

    Warns
    -----
    ConvergenceWarning, FitQualityWarning
        ``max_iter`` reached first; a result that is not a credible reflector.

    Examples
    --------
    >>> from bayes_mpem.lbl.simulation.simulate import simulate_survey
    >>> from bayes_mpem.lbl.em.em_paper import fit_paper_em
    >>> sim = simulate_survey("abe58", rng=1)
    >>> res = fit_paper_em(sim.survey.for_beacon("4"), sigma_dp=3.97)
    >>> abs(res.d0 - 2472) < 10
    True
    """
    data = check_fit_data(data)
    with options_as_input_errors():
        fixed_dp = check_options(path=path, pol=pol, alpha=alpha, sigma_dp=sigma_dp)
        check_positive("sigma_mp2_init", sigma_mp2_init)
        check_positive("tol", tol)
        check_int("max_iter", max_iter, minimum=1)
        check_finite("d0_init", d0_init)
    geom = BeaconGeometry.from_data(data)
    s_dp = fixed_dp or estimate_sigma_dp(geom)

    def message(run):
        d0, s_mp = run.params
        return (f"beacon {data.beacon}: the paper's EM did not converge in {run.n_iter} "
                f"iterations (d0={d0:.2f} m, sigma_mp={s_mp:.3g} m"
                + (", sigma_MP collapsed to 0)" if not s_mp > 0 else ")"))

    run = run_em(_PaperEM(geom, s_dp, pol, alpha, path),
                 (float(d0_init), float(np.sqrt(sigma_mp2_init))), tol=tol, max_iter=max_iter,
                 warn=message)
    (d0, s_mp), resp = run.params, run.resp
    converged = run.converged and not _stalled(run, alpha, tol, data.beacon)
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
        n_iter=run.n_iter,
        converged=converged,
        loglik=None,
        history={k: np.asarray(v) for k, v in run.history.items()},
        first_resp=run.first_resp,
        settings={"pol": float(pol), "alpha": float(alpha), "d0_init": float(d0_init),
                  "sigma_mp2_init": float(sigma_mp2_init), "tol": float(tol),
                  "sigma_dp_fixed": sigma_dp is not None},
    ), data, 0.0)
