"""Expectation-Maximization for one beacon: the paper's EM and a mixture EM.

* :func:`fit_paper_em` follows eqs. 3-10 of the paper as written: chi-square
  tail probabilities in the E-step, the ``Pol`` rule for outliers, the
  per-range plane-height average of eq. 8 blended by ``alpha`` (eq. 10), and
  eq. 9 (as a variance). Every interpretation is listed in ``docs/paper-em.md``.
* :func:`fit_mixture_em` (the default) maximises the likelihood of the
  density mixture of :mod:`bayes_mpem.mixture`. Each iteration is a
  generalised EM step (the plane height is improved by safeguarded
  Gauss-Newton, the rest in closed form), so the log-likelihood never
  decreases. With ``ssp=`` it predicts the ranges through a sound-speed
  profile (refracted rays, :mod:`bayes_mpem.refraction`) instead of straight
  lines.

Both return an :class:`EMResult` whose class probabilities come from a final
E-step at the returned parameters.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import special

from . import geometry
from ._rng import RNGLike, as_generator
from .data import BeaconData
from .mixture import CLASSES, BeaconGeometry, e_step, gaussian_logpdf


class ConvergenceWarning(UserWarning):
    """An EM run stopped at ``max_iter`` before meeting its stopping rule."""


class FitQualityWarning(UserWarning):
    """A fit converged to something that is not a credible reflector (see ``EMResult.flags``)."""


def quality_flags(result, data: BeaconData, *, sigma_floor: float = 0.05) -> tuple:
    """Reasons why a fitted reflector is not credible (empty when it is).

    Parameters
    ----------
    result : EMResult
    data : BeaconData
    sigma_floor : float
        The scale floor the fit used.

    Returns
    -------
    tuple of str
        Checked: almost no range is multipath (fewer than 10 ranges' worth), the
        multipath scale stuck at its floor (collapsed onto a few ranges) or above
        100 m (no coherent multipath), almost no range on the direct path (a wrong
        beacon position or navigation), a plane above the sea surface, and (for a
        fit through a sound-speed profile) more than 1 % of the ranges with no
        eigenray at all.
    """
    flags = []
    n_mp = float(result.resp[:, 1].sum()) if result.n else 0.0
    if n_mp < 10:
        flags.append(f"only {n_mp:.1f} ranges' worth of multipath: no reflector identified")
    if result.sigma_mp <= 1.05 * sigma_floor:
        flags.append(f"sigma_MP = {result.sigma_mp:.3g} m is at its floor: the multipath "
                     "component collapsed onto a few ranges")
    elif result.sigma_mp > 100.0:
        flags.append(f"sigma_MP = {result.sigma_mp:.0f} m: no coherent multipath band")
    if result.n and float(result.resp[:, 0].mean()) < 0.01:
        flags.append("almost no range matches the direct path: check the beacon position "
                     "and the navigation")
    depth = float(data.position[2])
    if result.d0 > depth + 10.0:
        flags.append(f"the plane is {result.d0 - depth:.0f} m above the sea surface "
                     f"(d0 = {result.d0:.0f} m, beacon depth {depth:.0f} m)")
    rays = result.settings.get("refraction") if result.settings else None
    if rays and result.n and rays["no_ray"] > 0.01 * result.n:
        flags.append(f"{rays['no_ray']} of {result.n} ranges have no eigenray through the "
                     "sound-speed profile (neither direct nor multipath at the fitted plane): "
                     "they can only be outliers")
    return tuple(flags)


def _with_flags(result, data, sigma_floor):
    """``result`` with its quality flags set, warning once if there are any."""
    flags = quality_flags(result, data, sigma_floor=sigma_floor)
    if flags:
        warnings.warn(f"beacon {data.beacon} ({result.method} EM): " + "; ".join(flags),
                      FitQualityWarning, stacklevel=3)
    return dataclasses.replace(result, flags=flags)


@dataclass(frozen=True)
class EMResult:
    """Fit of one beacon.

    Attributes
    ----------
    beacon : str
        Beacon id.
    method : {"mixture", "paper"}
    path : {"triangle", "double"}
        Multipath geometry.
    d0 : float
        Height of the reflecting plane above the beacon (m).
    sigma_mp, sigma_dp : float
        Multipath and direct-path range scatter (m).
    weights : dict
        Mixing weights ``{"dp", "mp", "ol"}``. The paper's EM has none (its
        priors are equal and dropped); there they are the mean class
        probabilities, the quantity of the paper's Fig. 12c.
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities of every range (dp, mp, ol).
    rows : numpy.ndarray
        Positions of these ranges in the input table.
    n_iter : int
    converged : bool
    loglik : float or None
        Mixture log-likelihood at the returned parameters (mixture EM only).
    d0_se : float or None
        Approximate standard error of ``d0`` (m, mixture EM only):
        ``sigma_mp / sqrt(sum_k p_mp(k) (d z_MP / d d0)_k^2)``, the Fisher
        information of the multipath ranges given their class probabilities.
        Calibrated on simulated surveys (``docs/recovery.md``).
    flags : tuple of str
        Why the result is not a credible reflector (:func:`quality_flags`);
        empty for a good fit. A :class:`FitQualityWarning` repeats them.
    history : dict of numpy.ndarray
        Per-iteration values, index 0 being the initial state: ``d0``,
        ``sigma_mp``, ``sigma_dp``, ``p_dp``, ``p_mp``, ``p_ol`` (mean class
        probabilities) and, for the mixture EM, ``loglik``.
    first_resp : numpy.ndarray
        Class probabilities after the first E-step (the paper's Fig. 7).
    settings : dict
        The options the fit ran with.
    """

    beacon: str
    method: str
    path: str
    d0: float
    sigma_mp: float
    sigma_dp: float
    weights: dict
    resp: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    n_iter: int
    converged: bool
    loglik: float | None
    history: dict = field(repr=False)
    first_resp: np.ndarray = field(repr=False)
    settings: dict = field(default_factory=dict)
    d0_se: float | None = None
    flags: tuple = ()

    @property
    def n(self) -> int:
        """Number of ranges used."""
        return int(self.resp.shape[0])

    @property
    def labels(self) -> np.ndarray:
        """Most probable class of every range (``"dp"``, ``"mp"`` or ``"ol"``)."""
        return np.asarray(CLASSES)[np.argmax(self.resp, axis=1)]

    @property
    def class_fractions(self) -> dict:
        """Fraction of ranges labelled dp, mp and ol."""
        lab = np.argmax(self.resp, axis=1)
        return {c: float(np.mean(lab == j)) if self.n else float("nan")
                for j, c in enumerate(CLASSES)}

    def to_dict(self) -> dict:
        """JSON-ready summary (no per-range arrays)."""
        return {
            "d0": self.d0,
            "sigma_mp": self.sigma_mp,
            "sigma_dp": self.sigma_dp,
            "weights": dict(self.weights),
            "class_fractions": self.class_fractions,
            "n": self.n,
            "iterations": self.n_iter,
            "converged": self.converged,
            "loglik": self.loglik,
            "d0_se": self.d0_se,
            "flags": list(self.flags),
            "method": self.method,
            "path": self.path,
            "settings": dict(self.settings),
        }


# --------------------------------------------------------------------------
# shared helpers


def estimate_sigma_dp(geom: BeaconGeometry, *, window: float = 50.0) -> float:
    """Robust direct-path scatter from residuals ``z - L_direct``.

    Residuals within ``window`` m of the direct path are trimmed iteratively
    at 3 sigma (starting from the MAD), a robust stand-in for the paper's
    least-squares fit of sigma_DP.

    Parameters
    ----------
    geom : BeaconGeometry
    window : float
        Initial half-width (m) of the residuals considered.

    Returns
    -------
    float
        Standard deviation (m); 1.0 if fewer than 5 ranges fall in the window.
    """
    r = geom.z - geom.direct
    r = r[np.abs(r) < window]
    if r.size < 5:
        return 1.0
    s = 1.4826 * np.median(np.abs(r - np.median(r)))
    for _ in range(20):
        keep = r[np.abs(r - r.mean()) < 3.0 * max(s, 1e-3)]
        s_new = float(keep.std()) if keep.size >= 5 else s
        if abs(s_new - s) < 1e-6:
            break
        s = s_new
    return max(float(s), 1e-3)


def _wdot(w, x):
    """``sum(w * x)`` without BLAS.

    ``np.dot`` on 1-D arrays calls a multi-threaded BLAS ``ddot`` that spin-waits
    for a busy core: on 2 cores with another process running it made the EM 40x
    slower (measured, ``benchmarks/bench_em.py``). A NumPy reduction does not.
    """
    return float(np.add.reduce(w * x))


def _check_positive(name, value, *, allow_none=False):
    if value is None and allow_none:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a positive number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: expected a positive number, got {value!r}")
    return v


def check_options(*, path="triangle", weights="learned", pol=0.05, alpha=0.5, sigma_dp=None):
    """Validate the options of both EMs (``ValueError`` naming the option); used up front.

    Returns
    -------
    float or None
        ``sigma_dp`` as a float (``None`` when it is to be estimated).
    """
    geometry.check_path(path)
    if weights not in ("learned", "equal"):
        raise ValueError(f"weights: expected 'learned' or 'equal', got {weights!r}")
    if not 0.0 < float(pol) < 1.0:
        raise ValueError(f"pol: expected a number in (0, 1), got {pol!r}")
    if not 0.0 < float(alpha) <= 1.0:
        raise ValueError(f"alpha: expected a number in (0, 1], got {alpha!r}")
    return _check_positive("sigma_dp", sigma_dp, allow_none=True)


def _check_max_iter(max_iter):
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter: expected an integer >= 1, got {max_iter!r}")


def _mean_resp_history(resp):
    return resp.mean(axis=0) if resp.size else np.full(3, np.nan)


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
        (:func:`~bayes_mpem.geometry.invert_plane_height`); they do not depend
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
    d0_avg = float(_wdot(gamma_mp[ok], d0k[ok]) / wsum) if wsum > 0 else d0_prev
    d0 = (1.0 - alpha) * d0_prev + alpha * d0_avg
    res2 = (geom.z - geom.multipath(d0, path)) ** 2
    g = gamma_mp.sum()
    var = float(_wdot(gamma_mp, res2) / g) if g > 0 else float("nan")
    return d0, float(np.sqrt(var))


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
    """The paper's EM, as written (eqs. 3-10).

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
    >>> from bayes_mpem.simulate import simulate_survey
    >>> from bayes_mpem.em import fit_paper_em
    >>> sim = simulate_survey("abe58", rng=1)
    >>> res = fit_paper_em(sim.survey.for_beacon("4"), sigma_dp=3.97)
    >>> abs(res.d0 - 2472) < 10
    True
    """
    fixed_dp = check_options(path=path, pol=pol, alpha=alpha, sigma_dp=sigma_dp)
    _check_positive("sigma_mp2_init", sigma_mp2_init)
    _check_positive("tol", tol)
    _check_max_iter(max_iter)
    if not np.isfinite(float(d0_init)):
        raise ValueError(f"d0_init: expected a finite number, got {d0_init!r}")
    geom = BeaconGeometry.from_data(data)
    s_dp = fixed_dp or estimate_sigma_dp(geom)
    d0, s_mp = float(d0_init), float(np.sqrt(sigma_mp2_init))
    d0k = geometry.invert_plane_height(geom.z, geom.h, geom.dz, path, direct=geom.direct)
    hist = {k: [] for k in ("d0", "sigma_mp", "sigma_dp", "p_dp", "p_mp", "p_ol")}

    def record(resp):
        hist["d0"].append(d0)
        hist["sigma_mp"].append(s_mp)
        hist["sigma_dp"].append(s_dp)
        for c, m in zip(CLASSES, _mean_resp_history(resp), strict=True):
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
    if not converged:
        warnings.warn(
            f"beacon {data.beacon}: the paper's EM did not converge in {it} iterations "
            f"(d0={d0:.2f} m, sigma_mp={s_mp:.3g} m"
            + (", sigma_MP collapsed to 0)" if not s_mp > 0 else ")"),
            ConvergenceWarning,
            stacklevel=2,
        )
    mean = _mean_resp_history(resp)
    return _with_flags(EMResult(
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


# --------------------------------------------------------------------------
# the mixture EM


@dataclass
class _State:
    d0: float
    sigma_dp: float
    sigma_mp: float
    weights: np.ndarray


def _weighted_sse(geom, r, d0, path):
    res = geom.z - geom.multipath(d0, path)
    return float(_wdot(r, res * res)), res


def _update_d0(geom, r, d0, path, lo, hi, max_steps=5):
    """Safeguarded Gauss-Newton on the weighted SSE: never increases it."""
    sse, res = _weighted_sse(geom, r, d0, path)
    for _ in range(max_steps):
        jac = geom.multipath_derivative(d0, path)
        den = float(_wdot(r, jac * jac))
        if den <= 0:
            break
        step = float(_wdot(r, res * jac)) / den
        for _ in range(30):
            cand = min(max(d0 + step, lo), hi)
            sse_c, res_c = _weighted_sse(geom, r, cand, path)
            if sse_c <= sse:
                break
            step *= 0.5
        else:
            break
        moved = abs(cand - d0)
        d0, sse, res = cand, sse_c, res_c
        if moved < 1e-6:
            break
    return d0, sse


def mixture_m_step(geom, resp, state, path, *, fit_sigma_dp, fit_weights, sigma_floor, d0_bounds):
    """M-step of the mixture EM (a generalised one for ``d0``).

    Parameters
    ----------
    geom : BeaconGeometry
    resp : numpy.ndarray
        ``(n, 3)`` responsibilities.
    state : _State
        Current parameters (``d0`` is the Gauss-Newton start).
    path : {"triangle", "double"}
    fit_sigma_dp, fit_weights : bool
        Whether sigma_DP and the weights are free.
    sigma_floor : float
        Lower bound on both scales (m), against collapse onto single ranges.
    d0_bounds : tuple of float

    Returns
    -------
    _State
    """
    r_dp, r_mp = resp[:, 0], resp[:, 1]
    d0, sse = _update_d0(geom, r_mp, state.d0, path, *d0_bounds)
    n_mp = r_mp.sum()
    s_mp = max(np.sqrt(sse / n_mp), sigma_floor) if n_mp > 0 else state.sigma_mp
    s_dp = state.sigma_dp
    if fit_sigma_dp and r_dp.sum() > 0:
        rd = geom.z - geom.direct
        s_dp = max(np.sqrt(_wdot(r_dp, rd * rd) / r_dp.sum()), sigma_floor)
    w = resp.mean(axis=0) if fit_weights else state.weights
    return _State(float(d0), float(s_dp), float(s_mp), np.asarray(w, float))


def _run_mixture(geom, state, path, *, fit_sigma_dp, fit_weights, sigma_floor, tol, max_iter,
                 d0_bounds):
    ll, resp = e_step(geom, state.d0, state.sigma_dp, state.sigma_mp, state.weights, path)
    first = resp
    hist = {k: [] for k in ("d0", "sigma_mp", "sigma_dp", "p_dp", "p_mp", "p_ol", "loglik",
                            "w_dp", "w_mp", "w_ol")}

    def record():
        hist["d0"].append(state.d0)
        hist["sigma_mp"].append(state.sigma_mp)
        hist["sigma_dp"].append(state.sigma_dp)
        hist["loglik"].append(ll)
        for j, c in enumerate(CLASSES):
            hist["p_" + c].append(float(resp[:, j].mean()))
            hist["w_" + c].append(float(state.weights[j]))

    record()
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        state = mixture_m_step(geom, resp, state, path, fit_sigma_dp=fit_sigma_dp,
                               fit_weights=fit_weights, sigma_floor=sigma_floor,
                               d0_bounds=d0_bounds)
        ll_old = ll
        ll, resp = e_step(geom, state.d0, state.sigma_dp, state.sigma_mp, state.weights, path)
        record()
        if abs(ll - ll_old) <= tol * max(geom.n, 1):
            converged = True
            break
    return state, ll, resp, first, hist, it, converged


def histogram_modes(v, k, *, width=5.0, sep=25.0, min_count=-1):
    """The ``k`` strongest modes of ``v``: centres of ``width`` bins of a 3-bin smoothed
    histogram, at least ``sep`` apart, with a smoothed count above ``min_count`` (default:
    any bin, empty ones included)."""
    nb = int(min(max((v.max() - v.min()) / width, 1), 20000))
    counts, edges = np.histogram(v, bins=nb)
    smooth = np.convolve(counts, np.ones(3), mode="same")[:counts.size] if counts.size >= 3 \
        else counts.astype(float)
    out = []
    for i in np.argsort(smooth)[::-1]:
        if smooth[i] <= min_count:
            break
        c = 0.5 * (edges[i] + edges[i + 1])
        if all(abs(c - o) > sep for o in out):
            out.append(float(c))
        if len(out) >= k:
            break
    return out


def _d0_candidates(geom, sigma_dp, path, k):
    """Modes of the per-range plane heights, ranges near the direct path left out."""
    d0k = geom.invert_plane_height(path)
    far = np.abs(geom.z - geom.direct) > max(6.0 * sigma_dp, 10.0)
    v = d0k[np.isfinite(d0k) & far & (d0k >= geom.d0_min)]
    if v.size < 3:
        return []
    return histogram_modes(v, k)


def fit_mixture_em(
    data: BeaconData,
    *,
    path: str = "triangle",
    sigma_dp: float | None = None,
    weights: str = "learned",
    init: dict | None = None,
    n_init: int = 4,
    max_iter: int = 500,
    tol: float = 1e-8,
    sigma_floor: float = 0.05,
    subsample: int = 20000,
    rng: RNGLike = None,
    ssp=None,
    sound_speed: float | None = None,
) -> EMResult:
    """Maximum-likelihood fit of the density mixture for one beacon.

    Parameters
    ----------
    data : BeaconData
        Replies of one beacon.
    path : {"triangle", "double"}
        Multipath geometry.
    sigma_dp : float, optional
        Fix the direct-path scatter (m); estimated from the data if omitted.
    weights : {"learned", "equal"}
        Learn the mixing weights (default) or fix them at 1/3 each, the
        paper's equal priors.
    init : dict, optional
        Extra starting point, e.g. ``result.to_dict()`` of an earlier fit
        (keys ``d0``, ``sigma_mp``, ``sigma_dp``, ``weights``).
    n_init : int, default 4
        Number of data-driven starts: the strongest modes of the per-range
        plane heights :func:`~bayes_mpem.geometry.invert_plane_height`.
    max_iter : int, default 500
    tol : float, default 1e-8
        Stop when the log-likelihood gains less than ``tol`` per range.
    sigma_floor : float, default 0.05
        Lower bound on the scales (m).
    subsample : int, default 20000
        Starts are compared on a random subsample of at most this many
        ranges; only the best is run on all of them.
    rng : None, int or numpy.random.Generator
        Seeds the subsample.
    ssp : SoundSpeedProfile, optional
        Predict the direct and multipath ranges through this profile (refracted
        eigenrays, :mod:`bayes_mpem.refraction`) instead of straight lines;
        ``d0`` stays the height of the reflecting plane above the beacon. It
        must reach the deepest beacon or vehicle. Ranges with no eigenray of a
        class get zero density under it (with neither, they can only be
        outliers); the counts are in ``settings["refraction"]``.
    sound_speed : float, optional
        With ``ssp``, required: the nominal speed (m/s) the navigation used to
        turn travel times into ranges.

    Returns
    -------
    EMResult

    Raises
    ------
    ValueError
        A bad option, fewer than 3 ranges, ``sound_speed`` without ``ssp`` or
        ``ssp`` without ``sound_speed``, a profile that does not reach the beacon
        or vehicle.
    TypeError
        ``ssp`` not a :class:`~bayes_mpem.acoustics.SoundSpeedProfile`.

    Warns
    -----
    ConvergenceWarning
        When ``max_iter`` is reached first.
    FitQualityWarning
        When the result is not a credible reflector (:func:`quality_flags`).

    Examples
    --------
    >>> from bayes_mpem.simulate import simulate_survey
    >>> from bayes_mpem.em import fit_mixture_em
    >>> sim = simulate_survey("abe58", rng=1)
    >>> res = fit_mixture_em(sim.survey.for_beacon("4"), rng=0)
    >>> abs(res.d0 - 2472) < 3
    True
    """
    fixed_dp = check_options(path=path, weights=weights, sigma_dp=sigma_dp)
    if int(n_init) < 1:
        raise ValueError(f"n_init: expected an integer >= 1, got {n_init!r}")
    _check_max_iter(max_iter)
    _check_positive("tol", tol)
    if not float(sigma_floor) >= 0:
        raise ValueError(f"sigma_floor: expected a number >= 0, got {sigma_floor!r}")
    if data.n < 3:
        raise ValueError(f"beacon {data.beacon}: need at least 3 ranges to fit, got {data.n}")
    gen = as_generator(rng)
    if ssp is None:
        if sound_speed is not None:
            raise ValueError("sound_speed: only used with a sound-speed profile (ssp=...)")
        geom = BeaconGeometry.from_data(data)
    else:
        from .refraction import RefractedBeaconGeometry

        geom = RefractedBeaconGeometry.from_data(data, ssp, sound_speed)
    s_dp0 = fixed_dp or estimate_sigma_dp(geom)
    d0_bounds = (geom.d0_min, geom.hi + geom.d0_min + 1.0)
    opts = dict(fit_sigma_dp=fixed_dp is None, fit_weights=weights == "learned",
                sigma_floor=float(sigma_floor), d0_bounds=d0_bounds)

    starts = []
    if init is not None:
        w = init.get("weights", {})
        starts.append(_State(
            float(init["d0"]),
            fixed_dp or float(init.get("sigma_dp", s_dp0)),
            float(init.get("sigma_mp", max(3 * s_dp0, 5.0))),
            np.array([w.get(c, 1 / 3) for c in CLASSES], float)
            if weights == "learned" else np.full(3, 1 / 3),
        ))
    for d0 in _d0_candidates(geom, s_dp0, path, int(n_init)):
        starts.append(_State(d0, s_dp0, float(np.clip(3 * s_dp0, 5.0, 50.0)), np.full(3, 1 / 3)))
    if not starts:  # no multipath-like ranges at all: start at the data window
        starts.append(_State(float(np.clip(geom.hi, *d0_bounds)), s_dp0, 50.0, np.full(3, 1 / 3)))
    for s in starts:
        s.d0 = float(np.clip(s.d0, *d0_bounds))

    prefix = None
    if len(starts) > 1:
        sub, full = geom, geom.n <= subsample
        if not full:
            idx = np.sort(gen.choice(geom.n, size=int(subsample), replace=False))
            sub = geom.take(idx)
        runs = [_run_mixture(sub, s, path, tol=1e-6, max_iter=min(100, int(max_iter)), **opts)
                for s in starts]
        best_run = max(runs, key=lambda run: run[1])
        best = best_run[0]
        if full:  # the comparison ran on all the data: continue that run
            prefix, first = best_run[4], best_run[3]
    else:
        best = starts[0]

    used = len(prefix["d0"]) - 1 if prefix is not None else 0
    state, ll, resp, first_new, hist, it, converged = _run_mixture(
        geom, best, path, tol=float(tol), max_iter=int(max_iter) - used, **opts)
    if prefix is not None:
        hist = {k: prefix[k] + v[1:] for k, v in hist.items()}
        it += used
    else:
        first = first_new
    if not converged:
        warnings.warn(
            f"beacon {data.beacon}: mixture EM did not converge in {it} iterations "
            f"(d0={state.d0:.2f} m); raise max_iter or loosen tol",
            ConvergenceWarning,
            stacklevel=2,
        )
    jac = geom.multipath_derivative(state.d0, path)
    info = _wdot(resp[:, 1], jac * jac)
    d0_se = state.sigma_mp / np.sqrt(info) if info > 0 else float("inf")
    settings = {"weights": weights, "sigma_dp_fixed": fixed_dp is not None,
                "n_starts": len(starts), "tol": float(tol), "sigma_floor": float(sigma_floor)}
    if not geom.straight:
        settings.update(ssp=geom.ssp.source or repr(geom.ssp), sound_speed=geom.sound_speed,
                        refraction=geom.ray_counts(state.d0, path))
    return _with_flags(EMResult(
        beacon=data.beacon,
        method="mixture",
        path=path,
        d0=state.d0,
        sigma_mp=state.sigma_mp,
        sigma_dp=state.sigma_dp,
        weights={c: float(w) for c, w in zip(CLASSES, state.weights, strict=True)},
        resp=resp,
        rows=np.asarray(data.rows),
        n_iter=it,
        converged=converged,
        loglik=ll,
        history={k: np.asarray(v) for k, v in hist.items()},
        first_resp=first,
        settings=settings,
        d0_se=float(d0_se),
    ), data, float(sigma_floor))


__all__ = [
    "ConvergenceWarning",
    "EMResult",
    "FitQualityWarning",
    "quality_flags",
    "estimate_sigma_dp",
    "fit_mixture_em",
    "fit_paper_em",
    "gaussian_logpdf",
    "paper_e_step",
    "paper_m_step",
    "mixture_m_step",
]
