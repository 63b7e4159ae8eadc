"""Find the effect hidden in a survey: which of the paper's assumptions the data break.

Details: ``docs/diagnose.md``.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from ..._rng import RNGLike, as_generator
from ..._validate import check_choice, check_finite, check_int, check_range
from ...io.survey import load_survey
from ..model import geometry
from ..simulation.effects import EFFECTS, PER_BEACON, UNITS, split_term
from ..survey.survey import check_min_pings, fittable_beacons
from .ecm import fit_joint
from .evidence import check_effect_names, effect_detail, effect_evidence, effect_magnitude_se
from .model import ranges
from .residuals import beacon_flags, residual_checks
from .result import Diagnosis, Effect
from .search import Search
from .starts import baseline_start


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
    """Find which of the paper's assumptions the survey breaks, and by how much (docs/diagnose.md).

    Parameters
    ----------
    pings : str, pathlib.Path, pandas.DataFrame or Survey
        The pings table (``docs/input.md``) or a loaded survey.
    beacons : str, pathlib.Path or pandas.DataFrame, optional
        The beacons table (not needed with a Survey).
    effects : sequence of str, default all of :data:`~bayes_mpem.lbl.simulation.effects.EFFECTS`
        The candidate extensions.
    path : {"auto", "triangle", "double"}
        Multipath geometry; ``"auto"`` (default) the one the baseline finds likelier.
    n_folds : int, default 5
        Folds of the cross-validation.
    min_gain, min_z : float, default 4 and 2
        An effect is kept only if it raises the held-out log predictive density by more
        than ``min_gain`` nats and ``min_z`` standard errors of that gain.
    max_effects : int, default 3
    min_pings : int, default 30
        Beacons with fewer replies are left out.
    rng : None, int or numpy.random.Generator
    progress : bool, default True
        Print one line per step to stderr.

    Returns
    -------
    Diagnosis

    Raises
    ------
    bayes_mpem.exceptions.InputError
        For invalid input.
    ValueError
        For invalid options, or fewer than two beacons to fit.
    """
    check_choice("path", path, ("auto", *geometry.PATHS))
    effects = tuple(effects)
    check_effect_names(effects, "effects")
    check_int("n_folds", n_folds, minimum=2)
    check_min_pings(min_pings)
    check_finite("min_gain", min_gain)
    check_range("min_gain", min_gain, low=0, include_low=True)
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
    say = _progress if progress else _silent

    start, path, path_ll = baseline_start(d, fittable, path, gen)
    seed = int(gen.integers(2**31))
    base = fit_joint(d, (), start, path=path, **kw)
    say(f"baseline: {d.n} replies, {d.nb} beacons, {path} multipath, "
        f"log-likelihood {base.loglik:.1f}")
    search = Search(d=d, fittable=fittable, path=path, folds=folds, seed=seed, kw=kw, say=say)
    current, kept, candidates = search.run(base, effects, max_effects=int(max_effects),
                                           min_gain=min_gain, min_z=min_z)
    found = []
    for t, delta, se in kept:
        name, bid = split_term(t)
        found.append(Effect(
            name=name, magnitude=current.magnitudes(d)[t], unit=UNITS[name],
            beacons=list(d.ids) if bid is None else [bid], delta_elpd=delta, delta_elpd_se=se,
            magnitude_se=effect_magnitude_se(t, current),
            evidence=effect_evidence(t, current, d, delta, se, int(n_folds)),
            detail=effect_detail(t, current, d)))
    checks = residual_checks(current, d)
    settings = {"path": path, "path_loglik": path_ll, "n_folds": int(n_folds),
                "min_gain": float(min_gain),
                "min_z": float(min_z), "max_effects": int(max_effects),
                "candidates": list(effects), "min_pings": int(min_pings)}
    flags = beacon_flags(current, d, kw["sigma_floor"])
    found, withheld = withhold_not_credible(found, flags)
    return Diagnosis(effects=found, baseline=base, final=current, candidates=candidates,
                     residual_checks=checks, skipped=skipped, survey=survey, data=d,
                     settings=settings, beacon_flags=flags, withheld=withheld)


def withhold_not_credible(found, flags):
    """Split the effects kept into those reported as found and those a flagged fit carries.

    A beacon's own effect (``beacon_bias``, ``beacon_position``) is read off that beacon's
    final fit: when that fit is not credible (``flags``), the effect is no finding. One
    beacon's ranges logged two-way were reported as "beacon moved 1.35 km" beside "fit not
    credible".

    Parameters
    ----------
    found : list of Effect
        The effects the search kept.
    flags : dict
        Beacon id to the reasons its final fit is not credible
        (:func:`~.residuals.beacon_flags`).

    Returns
    -------
    found : list of Effect
    withheld : list of dict
        :meth:`Effect.to_dict` of each effect left out, with its ``withheld`` reason.
    """
    kept, withheld = [], []
    for e in found:
        bad = [b for b in e.beacons if flags.get(b)] if e.name in PER_BEACON else []
        if not bad:
            kept.append(e)
            continue
        why = "; ".join(f"beacon {b}'s fit is not credible ({'; '.join(flags[b])})"
                        for b in bad)
        withheld.append({**e.to_dict(), "withheld": why})
    return kept, withheld


def _progress(msg):
    print(f"[diagnose] {msg}", file=sys.stderr, flush=True)


def _silent(msg):
    pass
