"""Find the effect hidden in a survey: which of the paper's assumptions the data break.

The paper's model assumes one static reflector, a homogeneous medium, exact
navigation and a calibrated system. :func:`diagnose` fits that model to every
beacon at once (the *baseline*), then each extension of a fixed vocabulary
(:data:`~bayes_mpem.lbl.effects.EFFECTS`), and keeps an extension only
when it predicts held-out ranges clearly better (K-fold cross-validated log
predictive density). Effects are added greedily, so two effects present at
once are both found.

The joint model
---------------
For range ``i`` of beacon ``b`` at normalised time ``tau_i`` (0 at the first
ping of the survey, 1 at the last), with the vehicle at the reported position
plus the navigation correction ``tau_i (e_x, e_y)``:

* direct path ``mu_dp = k D_i + beta``, multipath ``mu_mp = k M_i(P_b + delta
  tau_i) + beta`` off a plane at depth ``P_b + delta tau_i``, a second
  multipath ``mu_mp2 = k M_i(P_2) + beta``, with ``k = 1 + f``;
* Gaussian scatter per beacon and class; outliers uniform over the beacon's
  listening window, or, with first-arrival detection, uniform between the
  window start and the direct path;
* learned mixing weights per beacon.

Each effect switches on one part: ``range_bias`` (``beta``, m),
``sound_speed`` (``f = factor - 1``), ``plane_drift`` (``delta``, m from the
first to the last ping), ``second_reflector`` (``P_2``, m, with its weight and
scatter per beacon), ``early_outliers`` (the first-arrival outlier density;
magnitude = fraction of replies that are outliers) and ``nav_drift`` (``|(e_x,
e_y)|``, m at the last ping). The baseline, all switched off, is the mixture
model of :mod:`bayes_mpem.lbl.likelihood`, fitted to all beacons together.

The model is :mod:`~bayes_mpem.lbl.diagnosis.model`, its fit (ECM)
:mod:`~bayes_mpem.lbl.diagnosis.ecm`, the wording of the
evidence :mod:`.evidence`, the residual checks :mod:`.residuals` and the
result :class:`~bayes_mpem.lbl.diagnosis.result.Diagnosis`.

Examples
--------
>>> from bayes_mpem.lbl.simulate import simulate_survey
>>> sim = simulate_survey("abe58", rng=2, n_cycles=700, effects={"range_bias": 6.0})
>>> dx = diagnose(sim.survey, rng=0, progress=False)
>>> [e.name for e in dx.effects]
['range_bias']
>>> abs(dx.effects[0].magnitude - 6.0) < 0.5
True
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..._rng import RNGLike, as_generator
from ..._validate import check_choice, check_finite, check_int, check_range
from ...io.survey import load_survey
from .. import geometry
from ..effects import EFFECTS, UNITS
from ..survey import check_min_pings, fittable_beacons
from .ecm import baseline_start, fit_joint, heldout, replant, start_for
from .evidence import (
    check_effect_names,
    effect_detail,
    effect_evidence,
    effect_magnitude_se,
    not_credible,
)
from .model import Ranges, ranges
from .residuals import beacon_flags, residual_checks
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
    effects : sequence of str, default all of :data:`~bayes_mpem.lbl.effects.EFFECTS`
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
    search = _Search(d=d, fittable=fittable, path=path, folds=folds, seed=seed, kw=kw, say=say)
    current, kept, candidates = search.run(base, effects, max_effects=int(max_effects),
                                           min_gain=min_gain, min_z=min_z)
    found = [Effect(name=name, magnitude=current.magnitudes(d)[name], unit=UNITS[name],
                    beacons=list(d.ids), delta_elpd=delta, delta_elpd_se=se,
                    magnitude_se=effect_magnitude_se(name, current),
                    evidence=effect_evidence(name, current, d, delta, se, int(n_folds)),
                    detail=effect_detail(name, current))
             for name, delta, se in kept]
    checks = residual_checks(current, d)
    settings = {"path": path, "path_loglik": path_ll, "n_folds": int(n_folds),
                "min_gain": float(min_gain),
                "min_z": float(min_z), "max_effects": int(max_effects),
                "candidates": list(effects), "min_pings": int(min_pings)}
    return Diagnosis(effects=found, baseline=base, final=current, candidates=candidates,
                     residual_checks=checks, skipped=skipped, survey=survey, data=d,
                     settings=settings, beacon_flags=beacon_flags(current, d, kw["sigma_floor"]))


def _progress(msg):
    print(f"[diagnose] {msg}", file=sys.stderr, flush=True)


def _silent(msg):
    pass


@dataclass(frozen=True)
class _Search:
    """The greedy forward search over effects, on fixed data, folds and geometry."""

    d: Ranges
    fittable: list
    path: str
    folds: np.ndarray
    seed: int
    kw: dict
    say: Callable

    def run(self, base, effects, *, max_effects, min_gain, min_z):
        """Add effects greedily; return ``(final fit, kept, candidates)``."""
        current = base
        cur_ho = heldout(self.d, (), base, self.folds, self.path, **self.kw)
        kept, candidates = [], []
        for rnd in range(1, max_effects + 1):
            trials = []
            for name in effects:
                if name in current.effects:
                    continue
                cand, trial = self.try_effect(current, cur_ho, name, rnd)
                candidates.append(cand)
                if trial is not None:
                    trials.append(trial)
            good = [t for t in trials if t[0] > min_gain and t[0] > min_z * t[1]]
            if not good:
                break
            delta, se, name, fit_e, ho = max(good, key=lambda t: t[0])
            for c in candidates:
                if c["round"] == rnd and c["name"] == name:
                    c["kept"] = True
            mag = fit_e.magnitudes(self.d)[name]
            kept.append((name, delta, se))
            current, cur_ho = fit_e, ho
            self.say(f"kept {name} = {mag:+.4g} {UNITS[name]}")
        return current, kept, candidates

    def fit(self, current, name):
        """Fit the model of ``current`` plus effect ``name`` (best of its starts and a replant).

        Returns the fit, or a note saying why there is none.
        """
        d, path = self.d, self.path
        eff = tuple(sorted(set(current.effects) | {name}, key=EFFECTS.index))
        starts = start_for(d, current, eff, path)
        if not starts:
            return None, "no starting point"
        try:
            fit_e = fit_joint(d, eff, starts, path=path, **self.kw)
        except ValueError as err:
            return None, str(err)
        fresh = replant(d, fit_e, self.fittable, path, self.seed)
        if fresh is not None:
            try:
                alt = fit_joint(d, eff, fresh, path=path, **self.kw)
                if alt.loglik > fit_e.loglik:
                    fit_e = alt
            except ValueError:
                pass
        return fit_e, None

    def try_effect(self, current, cur_ho, name, rnd):
        """Score effect ``name`` on top of ``current``: ``(candidate entry, trial or None)``."""
        d = self.d
        fit_e, note = self.fit(current, name)
        if fit_e is None:
            return {"round": rnd, "name": name, "delta_elpd": None, "se": None,
                    "kept": False, "note": note}, None
        ho = heldout(d, fit_e.effects, fit_e, self.folds, self.path, **self.kw)
        diff = ho - cur_ho
        delta = float(diff.sum())
        se = float(np.sqrt(d.n * np.var(diff)))
        why_not = not_credible(name, fit_e, d)
        trial = (delta, se, name, fit_e, ho) if why_not is None else None
        cand = {"round": rnd, "name": name, "delta_elpd": delta, "se": se,
                "magnitude": fit_e.magnitudes(d)[name], "kept": False,
                **({"note": why_not} if why_not else {})}
        self.say(f"round {rnd}: {name:16s} delta elpd {delta:+10.1f} ± {se:.1f}")
        return cand, trial
