"""``navigate``: the track jointly with every range's class and each reflector.

The estimator: ``docs/navigate.md``.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from ..._rng import RNGLike, as_generator
from ..._validate import check_choice, check_int, check_positive, check_probability
from ...exceptions import ConvergenceWarning, InputError, NavigationWarning
from ...io.survey import BeaconData, load_survey
from ...mixture.densities import CLASSES, gaussian_logpdf
from ..em.em_result import reflector_flags
from ..em.path_choice import AUTO, check_path_choice, choose_path
from ..model.geometry import PATHS
from . import ecm, observability, ranges
from .dive import Dive, build_dive
from .normal import (
    cross_covariances,
    global_covariance,
    marginal_covariances,
    solve,
    solve_columns,
)
from .objective import (
    Priors,
    State,
    missing_information,
    normal_equations,
    predictions,
)
from .result import Navigation

#: A beacon whose sea-surface bounce would lag the direct path by less than this (m, median
#: over its replies, on the dead reckoning) gets no multipath class: the vehicle is at the
#: surface and the two arrivals are one.
MIN_SEPARATION = 1.0

#: A multipath class is kept only where its bounce lags the direct path by this many scales.
MIN_LAG_SIGMAS = 3.0

#: ... and carries this many replies' worth of probability.
MIN_MP_REPLIES = 10.0

#: ... and raises the beacon's log-likelihood ratio (2 log LR) above this: calibrated on
#: simulated dives without multipath (benchmarks/navigate_ship.py).
MP_LR_THRESHOLD = 30.0

#: ECM iterations before a run that has not converged has its multipath classes checked
#: (a class that collapsed onto the direct path makes the ECM crawl).
PROBE_ITER = 60


def _check_reflectors(reflectors, dive: Dive) -> dict:
    out = {}
    for bid, r in (reflectors or {}).items():
        bid = str(bid)
        if bid not in dive.beacon_ids:
            raise InputError(f"reflectors: unknown beacon {bid!r}; known: {dive.beacon_ids}")
        try:
            out[bid] = {"d0": float(r["d0"]), "sigma_mp": check_positive(
                f"reflectors[{bid!r}]['sigma_mp']", r["sigma_mp"]),
                "path": check_choice(f"reflectors[{bid!r}]['path']",
                                     r.get("path", "triangle"), PATHS)}
        except (KeyError, TypeError):
            raise InputError(f"reflectors[{bid!r}]: expected a mapping with 'd0' and "
                             f"'sigma_mp' (and 'path'), got {r!r}") from None
    return out


def _fixed_resp(classes, dive: Dive):
    if classes is None:
        return None
    lab = np.asarray(classes, dtype=object)
    if lab.shape != (len(dive.survey),):
        raise InputError(f"classes: expected one label per input row ({len(dive.survey)}), "
                         f"got shape {lab.shape}")
    lab = lab[dive.rows]
    bad = np.flatnonzero(~np.isin(lab, CLASSES))
    if bad.size:
        raise InputError(f"classes[{dive.rows[bad[0]]}]: expected 'dp', 'mp' or 'ol' for a "
                         f"ping with a reply, got {lab[bad[0]]!r}")
    return (lab[:, None] == np.asarray(CLASSES)[None, :]).astype(float)


def _start(dive: Dive, settings: ecm.Settings, path: str, fixed: dict, sigma_dp) -> State:
    """Start at the dead reckoning, planes at the sea surface (or as given), equal weights."""
    nb = len(dive.beacon_ids)
    d0 = np.maximum(dive.beacon_xyz[:, 2], dive.d0_min)
    double = np.full(nb, path == "double")
    sigma_mp = np.full(nb, settings.sigma_floor)
    for bid, r in fixed.items():
        j = dive.beacon_ids.index(bid)
        d0[j], sigma_mp[j], double[j] = r["d0"], r["sigma_mp"], r["path"] == "double"
    w = np.where(settings.mp_beacons[:, None], 1.0 / 3.0, [0.5, 0.0, 0.5])
    return State(dive.dr.copy(), 0.0, 1.0, d0, double,
                 settings.sigma_floor if sigma_dp is None else float(sigma_dp), sigma_mp, w)


def _choose_paths(dive: Dive, state: State, settings: ecm.Settings, gen):
    """Per beacon with a multipath class, the geometry :func:`choose_path` prefers on the track."""
    records, changed = {}, False
    double, d0, s_mp = state.double.copy(), state.d0.copy(), state.sigma_mp.copy()
    p = state.track[dive.epoch]
    for j, bid in enumerate(dive.beacon_ids):
        if not settings.mp_beacons[j] or j not in settings.free_d0:
            continue
        m = dive.beacon == j
        data = BeaconData.from_arrays(dive.z[m], p[m, 0], p[m, 1], dive.zdepth[m],
                                      dive.beacon_xyz[j], time=dive.times[dive.epoch[m]],
                                      beacon=bid)
        choice = choose_path(data, AUTO, rng=gen, fit_warnings=False)
        records[bid] = choice.to_dict()
        if (choice.path == "double") != bool(double[j]):
            changed = True
            double[j] = choice.path == "double"
            d0[j] = max(choice.fit.d0, dive.d0_min[j])
            s_mp[j] = max(choice.fit.sigma_mp, settings.sigma_floor)
    return state.replace(double=double, d0=d0, sigma_mp=s_mp), records, changed


def _without_multipath_loglik(ldp, lol, iters: int = 200) -> float:
    """Log-likelihood of replies as direct path or outlier, the mixing weight refitted (EM)."""
    w = 0.9
    for _ in range(iters):
        a, b = np.log(w) + ldp, np.log1p(-w) + lol
        m = np.maximum(a, b)
        lse = m + np.log(np.exp(a - m) + np.exp(b - m))
        w = float(np.clip(np.mean(np.exp(a - lse)), 1e-6, 1.0 - 1e-6))
    return float(np.add.reduce(lse))


def multipath_support(dive: Dive, state: State, resp, lse, settings: ecm.Settings) -> dict:
    """Decide, per beacon with an estimated multipath class, whether the data support it.

    Three tests (bounce lag, class size, likelihood ratio against
    :data:`MP_LR_THRESHOLD`), described in ``docs/navigate.md``.

    Parameters
    ----------
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities at ``state``.
    lse : numpy.ndarray
        ``(n,)`` per-reply log-likelihood at ``state``.

    Returns
    -------
    dict
        ``{beacon index: (kept, lr, reason)}``; ``reason`` is None when kept.
    """
    pred = predictions(dive, state)
    ldp_all = gaussian_logpdf(dive.z - pred.direct, state.sigma_dp)
    lol_all = dive.log_ol
    out = {}
    for j in settings.free_d0:
        m = dive.beacon == j
        if not m.any():
            continue
        scale = max(state.sigma_dp, float(state.sigma_mp[j]))
        lag = float(np.median(pred.multipath[m] - pred.direct[m]))
        n_mp = float(resp[m, 1].sum())
        plane = float(dive.beacon_xyz[j, 2] - state.d0[j])
        lr = 2.0 * (float(np.add.reduce(lse[m]))
                    - _without_multipath_loglik(ldp_all[m], lol_all[m]))
        reason = None
        if lag < MIN_LAG_SIGMAS * scale:
            reason = (f"the fitted bounce lags the direct path by {lag:.2g} m (median), less "
                      f"than {MIN_LAG_SIGMAS:g} sigma ({scale:.2g} m): the two arrivals cannot "
                      "be told apart (vehicle or plane at the surface)")
        elif n_mp < MIN_MP_REPLIES or state.sigma_mp[j] <= 1.05 * settings.sigma_floor:
            reason = (f"only {n_mp:.1f} replies' worth of multipath (sigma_MP "
                      f"{state.sigma_mp[j]:.2g} m): no reflector identified")
        elif plane < -10.0:
            reason = f"the fitted plane is {-plane:.0f} m above the sea surface"
        elif lr < MP_LR_THRESHOLD:
            reason = (f"likelihood ratio {lr:.1f} with / without a multipath class, below "
                      f"{MP_LR_THRESHOLD:g}: the data do not support one")
        out[j] = (reason is None, lr, reason)
    return out


def _drop_multipath(state: State, settings: ecm.Settings, drop):
    """Return settings and state with the multipath class of ``drop`` switched off."""
    mp = settings.mp_beacons.copy()
    mp[list(drop)] = False
    free = tuple(j for j in settings.free_d0 if j not in drop)
    w = state.weights.copy()
    for j in drop:
        w[j, 1] = 0.0
        w[j] /= max(w[j].sum(), 1e-300)
    return (dataclasses.replace(settings, mp_beacons=mp, free_d0=free),
            state.replace(weights=w))


def _positive_definite(step, cov) -> bool:
    """Return whether the Schur complement and every epoch's covariance are positive definite."""
    try:
        if step.S.size:
            np.linalg.cholesky(step.S)
    except np.linalg.LinAlgError:
        return False
    det = cov[:, 0, 0] * cov[:, 1, 1] - cov[:, 0, 1] * cov[:, 1, 0]
    return bool(np.all(np.isfinite(cov)) and np.all(cov[:, 0, 0] > 0) and np.all(det > 0))


def _psd(cov):
    """Return each 2x2 block symmetrised, its eigenvalues floored at a tiny positive value."""
    sym = 0.5 * (cov + np.swapaxes(cov, 1, 2))
    val, vec = np.linalg.eigh(sym)
    val = np.maximum(val, 1e-12 * np.maximum(val.max(axis=1, keepdims=True), 1e-300))
    return np.einsum("kab,kb,kcb->kac", vec, val, vec)


#: Names of the information the uncertainty is taken from (``summary.json``'s ``information``).
INFORMATION = {
    "observed": "observed (Louis)",
    "complete": "complete-data (class-weighted Gauss-Newton)",
    "fallback": ("complete-data (class-weighted Gauss-Newton): the observed (Louis) information "
                 "was not positive definite, so the intervals ignore the class uncertainty"),
}


def _free_scales(dive, state, resp, settings):
    """Return the estimated noise scales as ``(a, b, name)``: their range terms' weights.

    sigma_DP and every sigma_MP that is estimated, above its floor and has replies.
    """
    floor = 1.001 * settings.sigma_floor
    out = []
    if not settings.fix_sigma_dp and state.sigma_dp > floor and resp[:, 0].sum() > 0:
        out.append((resp[:, 0] / state.sigma_dp ** 2, np.zeros(dive.n), "sigma_dp"))
    b = resp[:, 1] / state.sigma_mp[dive.beacon] ** 2
    for j, bid in enumerate(dive.beacon_ids):
        m = dive.beacon == j
        fixed = settings.fix_sigma_mp.size > j and settings.fix_sigma_mp[j]
        if (settings.mp_beacons[j] and not fixed
                and state.sigma_mp[j] > floor and resp[m, 1].sum() > 0):
            out.append((np.zeros(dive.n), np.where(m, b, 0.0), f"sigma_mp:{bid}"))
    return out


def propagate_scales(dive, state, resp, settings, ne, step, cov, gcov, cross):
    """Add the noise scales' uncertainty to the track's and the globals' covariances.

    The law of total variance to first order, ``log sigma_j`` with MacKay's evidence
    variance (``docs/navigate.md``, *The noise scales' uncertainty*).

    Parameters
    ----------
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities.
    ne : Normal
        The information behind ``cov`` (:func:`.objective.normal_equations`,
        less Louis' missing information where that was used).
    step : Step
        :func:`.normal.solve` of ``ne``.
    cov : numpy.ndarray
        ``(K, 2, 2)`` the track's covariances given the scales.
    gcov : numpy.ndarray
        ``(G, G)`` the globals'.
    cross : numpy.ndarray
        ``(K, 2, G)`` the track's with the globals.

    Returns
    -------
    cov, gcov, cross : numpy.ndarray
        With the scales' share added (the inputs unchanged where no scale is estimated).
    sd_log : dict
        ``{scale name: posterior sd of log sigma}``.

    References
    ----------
    MacKay, D. J. C. (1992). Bayesian interpolation. *Neural Computation* 4:415-447
    (the evidence's error bar on a noise level).
    """
    scales = _free_scales(dive, state, resp, settings)
    if not scales:
        return cov, gcov, cross, {}
    pri, fk = settings.priors, settings.free_range_scale
    zero = np.zeros(dive.n)
    base = normal_equations(dive, state, zero, zero, pri, settings.free_d0, fk)
    v_dp, v_mp = ecm.leverages(dive, state, resp, settings)
    if v_dp is None:
        v_dp = v_mp = zero
    cols_p, cols_g, var = [], [], []
    for a, b, _ in scales:
        ne_j = normal_equations(dive, state, a, b, pri, settings.free_d0, fk)
        cols_p.append(2.0 * (ne_j.grad_p - base.grad_p))
        cols_g.append(2.0 * (ne_j.grad_g - base.grad_g))
        # a = p / sigma^2: n = sum p, gamma = sum p v / sigma^2
        n = float(np.add.reduce(a * state.sigma_dp ** 2 + b * state.sigma_mp[dive.beacon] ** 2))
        gamma = float(np.add.reduce(a * v_dp + b * v_mp))
        var.append(0.5 / max(n - min(gamma, (1.0 - ecm.MIN_DOF) * n), 1e-12))
    C_p, C_g = np.column_stack(cols_p), np.column_stack(cols_g)
    try:
        D_p, D_g = solve_columns(ne, step, C_p, C_g)
    except np.linalg.LinAlgError:
        return cov, gcov, cross, {}
    V = np.diag(var)
    k = dive.n_epochs
    Dk = D_p.reshape(k, 2, -1)
    cov = cov + np.einsum("kam,mn,kbn->kab", Dk, V, Dk)
    gcov = gcov + np.einsum("gm,mn,hn->gh", D_g, V, D_g)
    cross = cross + np.einsum("kam,mn,gn->kag", Dk, V, D_g)
    return cov, gcov, cross, {name: float(np.sqrt(v))
                              for v, (_, _, name) in zip(var, scales, strict=True)}


def _uncertainty(dive, run, settings):
    """Laplace covariances of the track and the globals, and which information was used.

    The observed (Louis) information where the classes are estimated and it is positive
    definite, else the complete-data one (``docs/navigate.md``).
    """
    a = run.resp[:, 0] / run.state.sigma_dp ** 2
    b = run.resp[:, 1] / run.state.sigma_mp[dive.beacon] ** 2
    fk = settings.free_range_scale
    ne = normal_equations(dive, run.state, a, b, settings.priors, settings.free_d0, fk)
    info, step, cov = INFORMATION["complete"], None, None
    if settings.model == "mixture" and settings.fixed_resp is None:
        dg, dB, dC = missing_information(dive, run.state, run.resp, settings.free_d0, fk)
        observed = ne._replace(diag=ne.diag - dg, B=ne.B - dB, C=ne.C - dC)
        try:
            step = solve(observed)
            cov = marginal_covariances(observed, step)
        except np.linalg.LinAlgError:
            step = None
        if step is not None and _positive_definite(step, cov):
            ne, info = observed, INFORMATION["observed"]
        else:
            step, cov, info = None, None, INFORMATION["fallback"]
    if step is None:
        step = solve(ne)
        cov = marginal_covariances(ne, step)
    if not _positive_definite(step, cov):  # rounding only: the information is positive definite
        cov = _psd(cov)
    gcov, cross = global_covariance(step), cross_covariances(step)
    record = None
    if settings.model == "mixture":
        given = cov
        cov, gcov, cross, sd_log = propagate_scales(dive, run.state, run.resp, settings, ne,
                                                    step, cov, gcov, cross)
        # how much the scales widen the ellipses: sd ratio, sqrt of the area ratio
        d0, d1 = np.linalg.det(given), np.linalg.det(cov)
        widen = np.sqrt(np.sqrt(np.divide(d1, d0, out=np.ones_like(d0), where=d0 > 0))) - 1.0
        record = {"sd_log_sigma": sd_log,
                  "ellipse_widening": {"median": float(np.median(widen)),
                                       "max": float(np.max(widen))}}
    gsd = np.sqrt(np.maximum(np.diag(gcov), 0.0))
    out = {"beta": float(gsd[0]), "scale": float(gsd[1])}
    out.update({f"d0:{dive.beacon_ids[j]}": float(gsd[2 + i])
                for i, j in enumerate(settings.free_d0)})
    if fk:
        out["range_scale"] = float(gsd[-1])
    return cov, out, gcov, cross, record, info


def surface_separation(dive: Dive) -> np.ndarray:
    """Return the median lag (m) of a surface bounce behind the direct path, per beacon.

    Returns
    -------
    numpy.ndarray
        ``(B,)``; 0 for a vehicle at the surface, NaN for a beacon without replies.
    """
    d0 = dive.beacon_xyz[:, 2]
    st = State(dive.dr, 0.0, 1.0, d0, np.zeros(d0.size, bool), 1.0, np.ones(d0.size),
               np.full((d0.size, 3), 1 / 3))
    pred = predictions(dive, st)
    lag = np.where(dive.zdepth > 0, pred.multipath - pred.direct, 0.0)
    return np.array([np.median(lag[dive.beacon == j]) if np.any(dive.beacon == j) else np.nan
                     for j in range(d0.size)])


def _settings(dive, opts, fixed, fixed_resp) -> ecm.Settings:
    counts = dive.replies_per_beacon()
    lag = surface_separation(dive)
    mp = np.array([opts["multipath"] == "signal" and opts["model"] == "mixture"
                   and (counts[j] >= opts["min_pings"] or bid in fixed)
                   and (lag[j] >= MIN_SEPARATION or bid in fixed)
                   for j, bid in enumerate(dive.beacon_ids)], bool)
    if fixed_resp is not None:  # the oracle: multipath where the classes say so
        mp = np.bincount(dive.beacon, weights=fixed_resp[:, 1], minlength=mp.size) > 0
    free = tuple(j for j, bid in enumerate(dive.beacon_ids) if mp[j] and bid not in fixed)
    fix_mp = np.array([bid in fixed for bid in dive.beacon_ids], bool)
    pri = Priors(q=opts["dr_noise"], start_sd=opts["start_sd"],
                 heading_sd=np.deg2rad(opts["heading_sd"]), scale_sd=opts["scale_sd"],
                 plane_sd=opts["plane_sd"])
    return ecm.Settings(priors=pri, model=opts["model"], mp_beacons=mp, free_d0=free,
                        fixed_resp=fixed_resp, fix_sigma_mp=fix_mp,
                        fix_sigma_dp=opts["sigma_dp"] is not None,
                        free_range_scale=bool(opts["range_scale"]),
                        anneal_start=opts["anneal_start"], max_iter=opts["max_iter"],
                        tol=opts["tol"])


def _no_mp_reason(multipath, model, count, min_pings, lag) -> str:
    if model != "mixture":
        return f"no multipath class in model={model!r}"
    if multipath == "outlier":
        return "multipath treated as outliers (multipath='outlier')"
    if count < min_pings:
        return f"{count} replies, fewer than min_pings={min_pings}: no multipath class"
    return (f"a sea-surface bounce would lag the direct path by {lag:.2g} m (median): the "
            "vehicle is at the surface, so multipath cannot be told from the direct path; "
            "no multipath class")


def _beacon_info(dive, run, settings, fixed, records, min_pings, multipath):
    counts = dive.replies_per_beacon()
    lag = surface_separation(dive)
    info = {}
    for j, bid in enumerate(dive.beacon_ids):
        d = {"mp": bool(settings.mp_beacons[j]), "d0_free": j in settings.free_d0,
             "path_choice": records.get(bid)}
        if d["mp"] and counts[j]:
            st = run.state
            d["flags"] = reflector_flags(run.resp[dive.beacon == j], float(st.sigma_mp[j]),
                                         float(dive.beacon_xyz[j, 2] - st.d0[j]),
                                         sigma_floor=settings.sigma_floor)
        if not d["mp"]:
            d["reason"] = _no_mp_reason(multipath, settings.model, counts[j], min_pings, lag[j])
        if bid in fixed:
            d["reason_fixed"] = "reflector given (not estimated)"
        info[bid] = d
    return info


def _merge(hist: dict, run: ecm.Run, index: int) -> None:
    """Append a run's history to ``hist``, with the run's index in ``hist["run"]``."""
    for k, v in run.history.items():
        hist.setdefault(k, []).extend(v)
    hist.setdefault("run", []).extend([index] * len(run.history.get("loglik", ())))


def _check_multipath(dive, state, settings, support, skip=()):
    """Check every multipath class at ``state`` (into ``support``); switch off the unsupported.

    Beacons in ``skip`` (a geometry just changed, their weights not yet refitted) are
    left alone. Returns the settings and state without them, and whether any was
    switched off.
    """
    resp, lse = ecm.e_step(dive, state, settings)
    found = {j: v for j, v in multipath_support(dive, state, resp, lse, settings).items()
             if j not in skip}
    support.update(found)
    drop = [j for j, (kept, _, _) in found.items() if not kept]
    if not drop:
        return settings, state, False
    settings, state = _drop_multipath(state, settings, drop)
    return settings, state, True


def _estimate(dive, settings, start, path, gen, timings):
    """Run the ECM, the path choice and the multipath check, then the ECM again where needed."""
    check = settings.model == "mixture" and settings.fixed_resp is None
    hist, records, support = {}, {}, {}
    t0 = time.perf_counter()
    run = ecm.run(dive, start, dataclasses.replace(
        settings, max_iter=min(settings.max_iter, PROBE_ITER)))
    n_iter, state, again = run.n_iter, run.state, not run.converged
    _merge(hist, run, 0)
    timings["ecm"] = time.perf_counter() - t0
    if path == AUTO and settings.free_d0:
        t0 = time.perf_counter()
        before = state.double
        state, records, changed = _choose_paths(dive, state, settings, gen)
        again |= changed
        timings["path_choice"] = time.perf_counter() - t0
    if again and n_iter < settings.max_iter:
        t0 = time.perf_counter()
        if check and settings.free_d0:
            moved = () if path != AUTO else np.flatnonzero(state.double != before).tolist()
            settings, state, _ = _check_multipath(dive, state, settings, support, moved)
        run = ecm.run(dive, state, dataclasses.replace(
            settings, max_iter=settings.max_iter - n_iter), anneal=False)
        n_iter += run.n_iter
        _merge(hist, run, 1)
        timings["ecm_continued"] = time.perf_counter() - t0
    if check and settings.free_d0:
        t0 = time.perf_counter()
        settings, state, dropped = _check_multipath(dive, run.state, settings, support)
        if dropped:
            run = ecm.run(dive, state, settings, anneal=False)
            n_iter += run.n_iter
            _merge(hist, run, 2)
        timings["multipath_check"] = time.perf_counter() - t0
    return run._replace(history=hist), n_iter, records, support, settings


def _check_options(opts):
    check_choice("model", opts["model"], ecm.MODELS)
    check_choice("multipath", opts["multipath"], ecm.MULTIPATH)
    check_path_choice(opts["path"])
    for k in ("dr_noise", "start_sd", "heading_sd", "scale_sd", "plane_sd", "anneal_start",
              "max_sd", "tol"):
        opts[k] = check_positive(k, opts[k])
    check_positive("sigma_dp", opts["sigma_dp"], allow_none=True)
    check_int("min_pings", opts["min_pings"], minimum=1)
    check_int("max_iter", opts["max_iter"], minimum=1)
    check_probability("ci", opts["ci"])


# long function: the steps of the estimator in order, each a call; splitting it would
# only pass its dozen locals around
def navigate(
    pings,
    beacons=None,
    *,
    dead_reckoning=None,
    multipath: str = "signal",
    model: str = "mixture",
    path: str = AUTO,
    dr_noise: float = 0.1,
    start_sd: float = 1000.0,
    heading_sd: float = 5.0,
    scale_sd: float = 0.05,
    plane_sd: float = 1000.0,
    sigma_dp: float | None = None,
    range_scale: bool = False,
    travel_times: str | None = None,
    profile=None,
    turnaround: float = 0.0,
    transducer_offset: float = 0.0,
    surface_depth: float = 0.0,
    classes=None,
    reflectors: dict | None = None,
    min_pings: int = 30,
    anneal_start: float = 100.0,
    max_sd: float = 10.0,
    max_iter: int = 300,
    tol: float = 1e-3,
    ci: float = 0.95,
    rng: RNGLike = None,
) -> Navigation:
    """Estimate the vehicle's track jointly with every range's class and each reflector.

    Parameters
    ----------
    pings : str, pathlib.Path, pandas.DataFrame or Survey
        The pings table: ``x``, ``y`` are the **dead-reckoned** position at each
        ping, ``depth`` the pressure depth (trusted). Pings with the same time
        form one epoch.
    beacons : str, pathlib.Path or pandas.DataFrame, optional
        The beacons table (not needed when ``pings`` is a Survey).
    dead_reckoning : str, pathlib.Path or pandas.DataFrame, optional
        A dead-reckoning table at its own rate, instead of the pings' ``x``, ``y``
        (:func:`~bayes_mpem.io.dead_reckoning.read_dead_reckoning`).
    multipath : {"signal", "outlier"}
        Multipath replies carry position information (default) or are outliers.
    model : {"mixture", "huber", "gate", "gaussian"}
        The mixture (default), or a baseline: every reply on the direct path with
        Huber's loss, with a 3-sigma residual gate, or Gaussian.
    path : {"auto", "triangle", "double"}
        Multipath geometry per beacon: chosen on the corrected track (default), or forced.
    dr_noise : float, default 0.1
        Random-walk level ``q`` of the dead reckoning (m / sqrt(s)).
    start_sd : float, default 1000
        Prior sd (m) of the first position about the first dead-reckoned fix.
    heading_sd : float, default 5
        Prior sd (degrees) of the heading bias.
    scale_sd : float, default 0.05
        Prior sd of the speed scale (about 1).
    plane_sd : float, default 1000
        Prior sd (m) of each plane height about the sea surface.
    sigma_dp : float, optional
        Fix sigma_DP (m); default estimated.
    range_scale : bool, default False
        Also estimate a factor on every predicted range (a sound-speed error), prior sd 0.01.
    travel_times : {"one-way", "two-way"}, optional
        The pings' ``range`` holds travel times (s), converted to equivalent
        straight-line ranges through ``profile`` (:mod:`.ranges`).
    profile : SoundSpeedProfile, str or float, optional
        With ``travel_times``: a profile, a profile file (depth m, speed m/s) or a
        constant sound speed (m/s).
    turnaround : float, default 0
        With ``travel_times``: the beacons' turn-around time (s).
    transducer_offset : float, default 0
        Depth of the transducer below the pings' ``depth`` (m, positive down).
    surface_depth : float, default 0
        With ``travel_times``: depth of the profile's 0 m in the tables' frame (m).
    classes : array_like, optional
        Known classes, one per input row (``"dp"``, ``"mp"``, ``"ol"``).
    reflectors : dict, optional
        ``{beacon: {"d0", "sigma_mp", "path"}}``: reflectors known, not estimated.
    min_pings : int, default 30
        A beacon with fewer replies gets no multipath class.
    anneal_start : float, default 100
        First floor (m) of the annealed scales; above the dead reckoning's error.
    max_sd : float, default 10
        Flag an epoch whose position sd (major axis, m) stays above this.
    max_iter : int, default 300
    tol : float, default 1e-3
        Converged when no position, plane height or scale moves more than ``tol`` m.
    ci : float, default 0.95
        Probability of the (Wald) intervals in the summary.
    rng : None, int or numpy.random.Generator
        Seeds the path choice's subsamples.

    Returns
    -------
    Navigation

    Raises
    ------
    InputError
        Invalid tables (file, line and column named), classes or reflectors.
    ValueError
        An invalid option.

    Warns
    -----
    NavigationWarning
        A stretch of the track, or a dead-reckoning nuisance, that the ranges do
        not correct.
    ConvergenceWarning
        ``max_iter`` reached first.

    Examples
    --------
    >>> from bayes_mpem.lbl.navigate import simulate_dive
    >>> sim = simulate_dive("abe58", rng=1, n_cycles=300)
    >>> nav = navigate(sim.survey, path="triangle")
    >>> err = nav.track - sim.true_track[["x", "y"]].to_numpy()
    >>> bool(np.sqrt((err ** 2).sum(axis=1).mean()) < 3.0)
    True
    """
    t_start = time.perf_counter()
    opts = dict(multipath=multipath, model=model, path=path, dr_noise=dr_noise,
                start_sd=start_sd, heading_sd=heading_sd, scale_sd=scale_sd, plane_sd=plane_sd,
                sigma_dp=sigma_dp, range_scale=bool(range_scale), min_pings=min_pings,
                anneal_start=anneal_start, max_sd=max_sd, max_iter=max_iter, tol=tol, ci=ci)
    _check_options(opts)
    gen = as_generator(rng)
    pings, beacons, opts["range_model"] = ranges.prepare(
        pings, beacons, travel_times=travel_times, profile=profile, turnaround=turnaround,
        transducer_offset=transducer_offset, surface_depth=surface_depth)
    survey = load_survey(pings, beacons)
    dive = build_dive(survey, dead_reckoning)
    fixed = _check_reflectors(reflectors, dive)
    settings = _settings(dive, opts, fixed, _fixed_resp(classes, dive))
    timings = {"load": time.perf_counter() - t_start}
    run, n_iter, records, support, settings = _estimate(
        dive, settings, _start(dive, settings, path, fixed, sigma_dp), path, gen, timings)
    if not run.converged:
        warnings.warn(f"navigate: the ECM did not converge in {n_iter} iterations; raise "
                      "max_iter (--max-iter) or loosen tol (--tol)", ConvergenceWarning,
                      stacklevel=2)
    t0 = time.perf_counter()
    cov, gsd, gcov, cross, scales, information = _uncertainty(dive, run, settings)
    flags = observability.assess(
        dive, cov, run.resp,
        {"heading_bias": (np.rad2deg(gsd["beta"]), opts["heading_sd"], "deg"),
         "speed_scale": (gsd["scale"], opts["scale_sd"], "")}, max_sd=opts["max_sd"],
        track=run.state.track)
    if flags:
        warnings.warn("navigate: " + observability.describe(flags), NavigationWarning,
                      stacklevel=2)
    timings["uncertainty"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    skipped = {bid: f"beacon {bid} has no reply" for bid, c in
               zip(dive.beacon_ids, dive.replies_per_beacon(), strict=True) if c == 0}
    info = _beacon_info(dive, run, settings, fixed, records, min_pings, multipath)
    for j, (kept, lr, reason) in support.items():
        bid = dive.beacon_ids[j]
        info[bid]["multipath_check"] = {"kept": kept, "likelihood_ratio": float(lr),
                                        "threshold": MP_LR_THRESHOLD}
        if not kept:
            info[bid]["reason"] = "multipath class switched off: " + reason
    opts.update(oracle_classes=classes is not None, reflectors_given=sorted(fixed),
                sigma_floor=settings.sigma_floor, information=information,
                scale_uncertainty=scales)
    return Navigation(dive=dive, state=run.state, cov=cov, global_sd=gsd, resp=run.resp,
                      beacons=info, skipped=skipped, flags=flags, n_iter=n_iter,
                      converged=run.converged, loglik=run.loglik, history=run.history,
                      options=opts, timings=timings, global_cov=gcov, track_global_cov=cross)
