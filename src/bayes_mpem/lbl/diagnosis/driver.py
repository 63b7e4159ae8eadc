"""Driver (moved from ``diagnose``)."""

from __future__ import annotations

import warnings

import numpy as np

from ..._rng import RNGLike, as_generator
from ...io.survey import load_survey
from .. import geometry
from ..survey import fittable_beacons
from .ecm import baseline_start, fit_joint, heldout, replant, start_for
from .evidence import (
    check_effect_names,
    effect_detail,
    effect_evidence,
    effect_magnitude_se,
    not_credible,
)
from .model import EFFECTS, UNITS, ranges
from .residuals import residual_checks
from .result import Diagnosis, Effect


def diagnose(
    pings,
    beacons=None,
    *,
    effects=EFFECTS,
    path: str = "auto",
    n_folds: int = 5,
    min_gain: float = 4.0,
    min_z: float = 2.0,
    max_effects: int = 3,
    min_pings: int = 30,
    rng: RNGLike = None,
    progress: bool = True,
) -> Diagnosis:
    """Find which of the paper's assumptions the survey breaks, and by how much.

    Parameters
    ----------
    pings : str, pathlib.Path, pandas.DataFrame or Survey
        The pings table (``docs/input.md``) or a loaded survey.
    beacons : str, pathlib.Path or pandas.DataFrame, optional
        The beacons table (not needed with a Survey).
    effects : sequence of str, default all of :data:`EFFECTS`
        The candidate extensions.
    path : {"auto", "triangle", "double"}
        Multipath geometry: one reflected leg (the paper's finding), both, or
        (default) whichever gives the baseline the higher likelihood.
    n_folds : int, default 5
        Folds of the cross-validation (replies assigned at random).
    min_gain : float, default 4
        An effect is kept only if it raises the held-out log predictive
        density by more than this many nats ...
    min_z : float, default 2
        ... and by more than ``min_z`` standard errors of that gain.
    max_effects : int, default 3
        Stop after this many effects.
    min_pings : int, default 30
        Beacons with fewer replies are left out.
    rng : None, int or numpy.random.Generator
        Seeds the folds and the baseline's starts.
    progress : bool, default True
        Print one line per step to stderr.

    Returns
    -------
    Diagnosis

    Raises
    ------
    bayes_mpem.data.InputError
        For invalid input.
    ValueError
        For invalid options, or fewer than two beacons to fit.
    """
    import sys

    if path != "auto":
        geometry.check_path(path)
    effects = tuple(effects)
    check_effect_names(effects, "effects")
    if int(n_folds) < 2:
        raise ValueError(f"n_folds: expected an integer >= 2, got {n_folds!r}")
    survey = load_survey(pings, beacons)
    gen = as_generator(rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fittable, skipped = fittable_beacons(survey, min_pings)
    skipped = dict(skipped)
    if not fittable:
        raise ValueError(f"no beacon has at least min_pings={min_pings} replies: {skipped}")
    d = ranges(survey, fittable)
    folds = gen.permutation(np.arange(d.n) % int(n_folds))
    kw = {"max_iter": 300, "tol": 1e-7, "sigma_floor": 0.05}

    def say(msg):
        if progress:
            print(f"[diagnose] {msg}", file=sys.stderr, flush=True)

    start, path, path_ll = baseline_start(d, fittable, path, gen)
    seed = int(gen.integers(2**31))
    base = fit_joint(d, (), start, path=path, **kw)
    say(f"baseline: {d.n} replies, {d.nb} beacons, {path} multipath, "
        f"log-likelihood {base.loglik:.1f}")
    current = base
    cur_ho = heldout(d, (), base, folds, path, **kw)
    kept, candidates = [], []
    for rnd in range(1, int(max_effects) + 1):
        trials = []
        for name in effects:
            if name in current.effects:
                continue
            eff = tuple(sorted(set(current.effects) | {name}, key=EFFECTS.index))
            starts = start_for(d, current, eff, path)
            if not starts:
                candidates.append({"round": rnd, "name": name, "delta_elpd": None, "se": None,
                                   "kept": False, "note": "no starting point"})
                continue
            try:
                fit_e = fit_joint(d, eff, starts, path=path, **kw)
            except ValueError as err:
                candidates.append({"round": rnd, "name": name, "delta_elpd": None, "se": None,
                                   "kept": False, "note": str(err)})
                continue
            fresh = replant(d, fit_e, fittable, path, seed)
            if fresh is not None:
                try:
                    alt = fit_joint(d, eff, fresh, path=path, **kw)
                    if alt.loglik > fit_e.loglik:
                        fit_e = alt
                except ValueError:
                    pass
            ho = heldout(d, eff, fit_e, folds, path, **kw)
            diff = ho - cur_ho
            delta = float(diff.sum())
            se = float(np.sqrt(d.n * np.var(diff)))
            why_not = not_credible(name, fit_e, d)
            if why_not is None:
                trials.append((delta, se, name, fit_e, ho))
            candidates.append({"round": rnd, "name": name, "delta_elpd": delta, "se": se,
                               "magnitude": fit_e.magnitudes(d)[name], "kept": False,
                               **({"note": why_not} if why_not else {})})
            say(f"round {rnd}: {name:16s} delta elpd {delta:+10.1f} ± {se:.1f}")
        good = [t for t in trials if t[0] > min_gain and t[0] > min_z * t[1]]
        if not good:
            break
        delta, se, name, fit_e, ho = max(good, key=lambda t: t[0])
        for c in candidates:
            if c["round"] == rnd and c["name"] == name:
                c["kept"] = True
        mag = fit_e.magnitudes(d)[name]
        kept.append((name, delta, se))
        current, cur_ho = fit_e, ho
        say(f"kept {name} = {mag:+.4g} {UNITS[name]}")
    found = []
    for name, delta, se in kept:
        mags = current.magnitudes(d)
        found.append(Effect(
            name=name, magnitude=mags[name], unit=UNITS[name], beacons=list(d.ids),
            delta_elpd=delta, delta_elpd_se=se, magnitude_se=effect_magnitude_se(name, current),
            evidence=effect_evidence(name, current, d, delta, se, int(n_folds)),
            detail=effect_detail(name, current)))
    checks = residual_checks(current, d)
    settings = {"path": path, "path_loglik": path_ll, "n_folds": int(n_folds),
                "min_gain": float(min_gain),
                "min_z": float(min_z), "max_effects": int(max_effects),
                "candidates": list(effects), "min_pings": int(min_pings)}
    return Diagnosis(effects=found, baseline=base, final=current, candidates=candidates,
                     residual_checks=checks, skipped=skipped, survey=survey, data=d,
                     settings=settings)
