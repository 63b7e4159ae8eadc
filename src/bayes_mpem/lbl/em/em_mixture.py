"""The mixture EM for one beacon: maximum likelihood of the dp / mp / ol mixture (docs/model.md)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..._rng import RNGLike, as_generator
from ..._validate import check_finite, check_int, check_positive, check_probability, check_range
from ...io.survey import BeaconData
from ...mixture.densities import CLASSES
from ...mixture.em import EMModel, best_run, run_em
from ...mixture.gauss_newton import safeguarded_step
from ..model.beacon_geometry import BeaconGeometry
from ..model.likelihood import e_step
from .em_result import (
    EMResult,
    check_fit_data,
    check_options,
    estimate_sigma_dp,
    options_as_input_errors,
    wdot,
    with_flags,
)

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
    return float(wdot(r, res * res)), res


def _update_d0(geom, r, d0, path, lo, hi, max_steps=5):
    """Safeguarded Gauss-Newton on the weighted SSE: never increases it."""
    sse, res = _weighted_sse(geom, r, d0, path)
    for _ in range(max_steps):
        jac = geom.multipath_derivative(d0, path)
        den = float(wdot(r, jac * jac))
        if den <= 0:
            break
        step = float(wdot(r, res * jac)) / den
        out = safeguarded_step(lambda x: _weighted_sse(geom, r, x, path), d0, step, sse,
                               bounds=(lo, hi))
        if out is None:
            break
        moved = abs(out.x - d0)
        d0, sse, res = out.x, out.value, out.aux
        if moved < 1e-6:
            break
    return d0, sse


def mixture_m_step(geom, resp, state, path, *, fit_sigma_dp, fit_weights, sigma_floor, d0_bounds):
    """M-step of the mixture EM (a generalised one for ``d0``).

    Parameters
    ----------
    resp : numpy.ndarray
        ``(n, 3)`` responsibilities.
    state : _State
        Current parameters (``d0`` is the Gauss-Newton start).
    fit_sigma_dp, fit_weights : bool
        Whether sigma_DP and the weights are free.
    sigma_floor : float
        Lower bound on both scales (m).
    """
    r_dp, r_mp = resp[:, 0], resp[:, 1]
    d0, sse = _update_d0(geom, r_mp, state.d0, path, *d0_bounds)
    n_mp = r_mp.sum()
    s_mp = max(np.sqrt(sse / n_mp), sigma_floor) if n_mp > 0 else state.sigma_mp
    s_dp = state.sigma_dp
    if fit_sigma_dp and r_dp.sum() > 0:
        rd = geom.z - geom.direct
        s_dp = max(np.sqrt(wdot(r_dp, rd * rd) / r_dp.sum()), sigma_floor)
    w = resp.mean(axis=0) if fit_weights else state.weights
    return _State(float(d0), float(s_dp), float(s_mp), np.asarray(w, float))


class _MixtureEM(EMModel):
    """The mixture EM as a :class:`~bayes_mpem.mixture.em.EMModel`: parameters a ``_State``."""

    def __init__(self, geom, path, **opts):
        self.geom, self.path, self.opts = geom, path, opts

    def e_step(self, state):
        return e_step(self.geom, state.d0, state.sigma_dp, state.sigma_mp, state.weights,
                      self.path)

    def m_step(self, state, resp):
        return mixture_m_step(self.geom, resp, state, self.path, **self.opts)

    def record(self, state, loglik, resp):
        out = {"d0": state.d0, "sigma_mp": state.sigma_mp, "sigma_dp": state.sigma_dp}
        out.update(("p_" + c, float(resp[:, j].mean())) for j, c in enumerate(CLASSES))
        out["loglik"] = loglik
        out.update(("w_" + c, float(state.weights[j])) for j, c in enumerate(CLASSES))
        return out


def histogram_modes(v, k, *, width=5.0, sep=25.0, min_count=-1):
    """Return the ``k`` strongest modes of ``v`` (bin centres) from a smoothed histogram.

    Parameters
    ----------
    width : float, default 5
        Bin width.
    sep : float, default 25
        Smallest separation of two modes.
    min_count : float, default -1
        A mode's 3-bin smoothed count must exceed this.

    Examples
    --------
    >>> histogram_modes(np.r_[np.full(50, 100.0), np.full(20, 300.0)], 2)
    [102.5, 297.5]
    """
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
        Learn the mixing weights (default) or fix them at 1/3 (the paper's).
    init : dict or EMResult, optional
        Extra starting point, e.g. ``result.to_dict()`` of an earlier fit: ``d0`` (m, finite)
        and optionally ``sigma_dp``, ``sigma_mp`` (m, > 0) and ``weights`` (``{"dp", "mp",
        "ol"}``, each in [0, 1]).
    n_init : int, default 4
        Data-driven starts: the strongest modes of the per-range plane heights.
    max_iter : int, default 500
    tol : float, default 1e-8
        Stop when the log-likelihood gains less than ``tol`` per range.
    sigma_floor : float, default 0.05
        Lower bound on the scales (m).
    subsample : int, default 20000
        Starts are compared on a random subsample of at most this many ranges (>= 1).
    rng : None, int or numpy.random.Generator
    ssp : SoundSpeedProfile, optional
        Predict the ranges along refracted eigenrays through this profile instead of straight
        lines (``docs/refraction.md``); it must reach the deepest beacon or vehicle.
    sound_speed : float, optional
        With ``ssp``, required: the nominal speed (m/s) that turned travel times into ranges.

    Returns
    -------
    EMResult

    Raises
    ------
    InputError
        ``data`` not a BeaconData (a Survey: ``survey.for_beacon(id)``), fewer than 3 ranges,
        a bad option or ``init`` (naming it, what was expected and what arrived).
    ValueError, TypeError
        ``ssp`` and ``sound_speed`` not given together, a profile that does not reach the
        beacon or vehicle; ``ssp`` not a profile.

    Warns
    -----
    ConvergenceWarning, FitQualityWarning
        ``max_iter`` reached first; a result that is not a credible reflector.

    Examples
    --------
    >>> from bayes_mpem.lbl.simulation.simulate import simulate_survey
    >>> from bayes_mpem.lbl.em.em_mixture import fit_mixture_em
    >>> sim = simulate_survey("abe58", rng=1)
    >>> res = fit_mixture_em(sim.survey.for_beacon("4"), rng=0)
    >>> abs(res.d0 - 2472) < 3
    True
    """
    data = check_fit_data(data)
    with options_as_input_errors():
        fixed_dp = check_options(path=path, weights=weights, sigma_dp=sigma_dp)
        check_int("n_init", n_init, minimum=1)
        check_int("max_iter", max_iter, minimum=1)
        check_positive("tol", tol)
        check_range("sigma_floor", sigma_floor, low=0, include_low=True)
        check_int("subsample", subsample, minimum=1)
        init = check_init(init)
    gen = as_generator(rng)
    geom = _geometry(data, ssp, sound_speed)
    s_dp0 = fixed_dp or estimate_sigma_dp(geom)
    d0_bounds = (geom.d0_min, geom.hi + geom.d0_min + 1.0)
    opts = dict(fit_sigma_dp=fixed_dp is None, fit_weights=weights == "learned",
                sigma_floor=float(sigma_floor), d0_bounds=d0_bounds)
    starts = _starts(geom, init, s_dp0, fixed_dp, weights, path, int(n_init), d0_bounds)
    init, resume = _best_start(geom, starts, path, opts, subsample=subsample,
                               max_iter=max_iter, gen=gen)
    run = run_em(_MixtureEM(geom, path, **opts), init, tol=float(tol) * max(geom.n, 1),
                 max_iter=int(max_iter), resume=resume,
                 warn=lambda run: f"beacon {data.beacon}: mixture EM did not converge in "
                 f"{run.n_iter} iterations (d0={run.params.d0:.2f} m); raise max_iter or "
                 "loosen tol")
    state, resp = run.params, run.resp
    jac = geom.multipath_derivative(state.d0, path)
    info = wdot(resp[:, 1], jac * jac)
    d0_se = state.sigma_mp / np.sqrt(info) if info > 0 else float("inf")
    settings = {"weights": weights, "sigma_dp_fixed": fixed_dp is not None,
                "n_starts": len(starts), "tol": float(tol), "sigma_floor": float(sigma_floor)}
    if not geom.straight:
        settings.update(ssp=geom.ssp.source or repr(geom.ssp), sound_speed=geom.sound_speed,
                        refraction=geom.ray_counts(state.d0, path))
    return with_flags(EMResult(
        beacon=data.beacon,
        method="mixture",
        path=path,
        d0=state.d0,
        sigma_mp=state.sigma_mp,
        sigma_dp=state.sigma_dp,
        weights={c: float(w) for c, w in zip(CLASSES, state.weights, strict=True)},
        resp=resp,
        rows=np.asarray(data.rows),
        n_iter=run.n_iter,
        converged=run.converged,
        loglik=run.loglik,
        history={k: np.asarray(v) for k, v in run.history.items()},
        first_resp=run.first_resp,
        settings=settings,
        d0_se=float(d0_se),
    ), data, float(sigma_floor))


def _geometry(data, ssp, sound_speed):
    """Straight-ray geometry, or refracted through ``ssp`` (then ``sound_speed`` is needed)."""
    if ssp is None:
        if sound_speed is not None:
            raise ValueError("sound_speed: only used with a sound-speed profile (ssp=...)")
        return BeaconGeometry.from_data(data)
    from ..model.refracted import RefractedBeaconGeometry

    return RefractedBeaconGeometry.from_data(data, ssp, sound_speed)


def check_init(init) -> dict | None:
    """Check ``fit_mixture_em``'s ``init``; return it as a dict of floats (None for none).

    Unchecked, ``d0=NaN`` or ``sigma_mp=-5`` gave a fit of NaN log-likelihood and zero weights
    (warned as not converged), a missing ``d0`` a ``KeyError``.

    Parameters
    ----------
    init : dict, EMResult or None
        ``d0`` (finite) and optionally ``sigma_dp``, ``sigma_mp`` (> 0), ``weights``
        (``{"dp", "mp", "ol"}`` in [0, 1], not all 0).

    Returns
    -------
    dict or None

    Raises
    ------
    ValueError
        Naming the key (``init['sigma_mp']``), what was expected and what arrived.
    """
    if init is None:
        return None
    if isinstance(init, EMResult):
        init = init.to_dict()
    if not isinstance(init, Mapping) or "d0" not in init:
        got = (f"keys {sorted(map(str, init))}" if isinstance(init, Mapping)
               else f"a {type(init).__name__}")
        raise ValueError("init: expected a mapping with 'd0', the plane height to start from "
                         f"(an EMResult or its to_dict()), got {got}")
    out = {"d0": check_finite("init['d0']", init["d0"])}
    for key in ("sigma_dp", "sigma_mp"):
        if init.get(key) is not None:
            out[key] = check_positive(f"init[{key!r}]", init[key])
    w = init.get("weights")
    if w is not None:
        if not isinstance(w, Mapping):
            raise ValueError("init['weights']: expected a mapping of 'dp', 'mp' and 'ol', got "
                             f"{w!r}")
        out["weights"] = {c: check_probability(f"init['weights'][{c!r}]", w[c],
                                               open_interval=False) for c in CLASSES if c in w}
        if not sum(out["weights"].get(c, 1 / 3) for c in CLASSES) > 0:
            raise ValueError(f"init['weights']: expected weights not all 0, got {dict(w)!r}")
    return out


def _starts(geom, init, s_dp0, fixed_dp, weights, path, n_init, d0_bounds):
    """List the starting states: ``init``, then the modes of the per-range plane heights."""
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
    for d0 in _d0_candidates(geom, s_dp0, path, n_init):
        starts.append(_State(d0, s_dp0, float(np.clip(3 * s_dp0, 5.0, 50.0)), np.full(3, 1 / 3)))
    if not starts:  # no multipath-like ranges at all: start at the data window
        starts.append(_State(float(np.clip(geom.hi, *d0_bounds)), s_dp0, 50.0, np.full(3, 1 / 3)))
    for s in starts:
        s.d0 = float(np.clip(s.d0, *d0_bounds))
    return starts


def _best_start(geom, starts, path, opts, *, subsample, max_iter, gen):
    """Compare the starts by short runs on a subsample of at most ``subsample`` ranges.

    Returns ``(best start, run)``: the winning run, to be continued, when the
    comparison ran on all the data, else ``None``.
    """
    if len(starts) == 1:
        return starts[0], None
    sub, full = geom, geom.n <= subsample
    if not full:
        idx = np.sort(gen.choice(geom.n, size=int(subsample), replace=False))
        sub = geom.take(idx)
    model = _MixtureEM(sub, path, **opts)
    best = best_run(run_em(model, s, tol=1e-6 * max(sub.n, 1), max_iter=min(100, int(max_iter)))
                    for s in starts)
    return best.params, best if full else None
