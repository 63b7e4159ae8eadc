"""The search over effects of the diagnosis: forward selection, then a backward step.

Details: ``docs/diagnose.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..simulation.effects import PER_BEACON, UNITS, split_term, term, term_order
from ..survey.model_checks import covariates, direct_path_checks, trend_checks
from .ecm import fit_joint, heldout
from .evidence import not_credible
from .model import Ranges, offsets, predict
from .params import BEACON_KEYS, SHARED_KEYS, without
from .starts import replant, start_for

#: A beacon whose direct-path mean residual is this many standard errors off ...
SUSPECT_Z = 3.0
#: ... or whose direct-path residuals trend with a covariate at this p-value (not
#: corrected for the number of checks: a screen, not a verdict) gets per-beacon candidates;
SUSPECT_P = 1e-3
#: so does a beacon whose direct-path weight fell below this (its direct path is off by
#: more than the fit could follow: the multipath family sits on it).
SUSPECT_DP = 0.05


def _n_parameters(t) -> int:
    """Return the number of mean parameters of a term (:data:`.params.SHARED_KEYS`, ...)."""
    name, bid = split_term(t)
    keys = BEACON_KEYS if bid is not None else SHARED_KEYS
    return len(keys.get(name, ())) or 1


def _suspects(fit, d: Ranges) -> list:
    """List the beacons whose direct-path residuals ``fit`` leaves unexplained."""
    mu = predict(d, fit.params, fit.effects, fit.path)
    ex, ey, _, dz = offsets(d, fit.params, fit.effects)
    cov = covariates(ex, ey, dz, d.time, d.vdepth)
    out = []
    for j, bid in enumerate(d.ids):
        sel = d.bi == j
        if fit.params.weights[j, 0] < SUSPECT_DP:  # no direct path left to check
            out.append(bid)
            continue
        r = d.z[sel] - mu["dp"][sel]
        s = float(fit.params.sigma[j, 0])
        off = direct_path_checks(r, fit.resp[sel, 0], s)
        trends = trend_checks({"dp": r}, {"dp": s}, {"dp": fit.resp[sel, 0]},
                              {k: v[sel] for k, v in cov.items()})
        if (any(abs(c["z"] or 0.0) > SUSPECT_Z for c in off)
                or any(c["p_value"] < SUSPECT_P for c in trends)):
            out.append(bid)
    return out


@dataclass(frozen=True)
class Search:
    """The search over effects on fixed data, folds and geometry.

    Parameters
    ----------
    folds : numpy.ndarray
        Per reply, its cross-validation fold.
    seed : int
        Seeds the replants.
    kw : dict
        Options of :func:`~bayes_mpem.lbl.diagnosis.ecm.fit_joint`.
    say : callable
        ``say(message)``: the progress report.
    """

    d: Ranges
    fittable: list
    path: str
    folds: np.ndarray
    seed: int
    kw: dict
    say: Callable

    def run(self, base, effects, *, max_effects, min_gain, min_z):
        """Add effects greedily, then drop those that no longer earn their place.

        Parameters
        ----------
        min_gain, min_z : float
            The keep rule.

        Returns
        -------
        current : JointFit
        kept : list of tuple
            ``(term, delta, se)`` of the effects kept.
        candidates : list of dict
            Every fit tried.
        """
        state = {"fit": base, "ho": heldout(self.d, (), base, self.folds, self.path, **self.kw),
                 "kept": [], "round": 0, "tried": {}}
        candidates = []
        rule = {"min_gain": min_gain, "min_z": min_z}
        per_beacon = any(e in PER_BEACON for e in effects)
        first = _suspects(base, self.d) if per_beacon else []
        # shared effects first (one clock, one sound speed, one navigation explain every
        # beacon at once), then all, per-beacon ones on the beacons still unexplained; but
        # when only a minority of beacons is unexplained at the baseline, their own effects
        # first (four shared parameters can mimic one beacon's bias)
        stages = ("own", "all") if 0 < len(first) < self.d.nb / 2 else ("shared", "all")
        for stage in stages:
            if stage == "all" and not (per_beacon and _suspects(state["fit"], self.d)):
                break
            # each stage may add max_effects terms: the shared stage may have used them all
            # on what one beacon's own effect explains; the backward step then prunes
            self.forward(state, effects, candidates, stage=stage,
                         max_effects=len(state["kept"]) + max_effects, **rule)
            state["fit"], state["ho"], state["kept"] = self.backward(
                state["fit"], state["ho"], state["kept"], candidates, **rule)
        while len(state["kept"]) > max_effects:  # more than asked for: drop the weakest
            state["fit"], state["ho"], state["kept"] = self.backward(
                state["fit"], state["ho"], state["kept"], candidates,
                min_gain=np.inf, min_z=np.inf, once=True)
        return state["fit"], state["kept"], candidates

    def forward(self, state, effects, candidates, *, stage, max_effects, min_gain, min_z):
        """Add the best term while one meets the keep rule (``state`` updated in place).

        Parameters
        ----------
        state : dict
            ``fit``, ``ho`` (its held-out densities), ``kept``.
        candidates : list of dict
            Every term tried (appended to).
        """
        while len(state["kept"]) < max_effects:
            current, cur_ho = state["fit"], state["ho"]
            state["round"] += 1
            rnd = state["round"]
            trials = []
            for t in self.terms(current, effects, stage=stage):
                # the same term on the same fit was scored in the last round of the shared
                # search: reuse it rather than fit it again
                key = (id(current), t)
                seen = state["tried"].get(key)
                if seen is None or seen[0] is not current:  # (the fit itself, not a reused id)
                    seen = state["tried"][key] = (current, *self.try_effect(current, cur_ho,
                                                                            t, rnd))
                _, cand, trial = seen
                candidates.append({**cand, "round": rnd})
                if trial is not None:
                    trials.append(trial)
            good = [t for t in trials if t[0] > min_gain and t[0] > min_z * t[1]]
            if not good:
                return
            best = max(t[0] for t in good)
            delta, se, name, fit_e, ho = min(
                (t for t in good if t[0] >= best - min_gain),
                key=lambda t: (_n_parameters(t[2]), -t[0]))
            for c in candidates:
                if c["round"] == rnd and c["name"] == name:
                    c["kept"] = True
            state["kept"].append((name, delta, se))
            state["fit"], state["ho"] = fit_e, ho
            self.say(f"kept {name} = {fit_e.magnitudes(self.d)[name]:+.4g} "
                     f"{UNITS[split_term(name)[0]]}")

    def terms(self, current, effects, *, stage="all"):
        """Terms to try on top of ``current``: shared effects, then suspect beacons' own."""
        shared = ([e for e in effects if e not in PER_BEACON and e not in current.effects]
                  if stage != "own" else [])
        per = [e for e in effects if e in PER_BEACON] if stage != "shared" else []
        beacons = _suspects(current, self.d) if per else []
        return shared + [term(e, b) for b in beacons for e in per
                         if term(e, b) not in current.effects]

    def backward(self, current, cur_ho, kept, candidates, *, min_gain, min_z, once=False):
        """Drop kept effects whose removal costs less than the keep rule, weakest first.

        Parameters
        ----------
        cur_ho : numpy.ndarray
            Its held-out log densities.
        once : bool, default False
            Drop at most one effect.

        Returns
        -------
        fit, held_out, kept
            The kept effects each with what removing it from the final model costs.
        """
        d = self.d
        while kept:
            costs = []
            for name, _, _ in kept:
                rest = tuple(t for t in current.effects if t != name)
                fit_r = self.refit(rest, [without(current.params, name, d.ids)])
                if fit_r is None:
                    continue
                ho = heldout(d, rest, fit_r, self.folds, self.path, **self.kw)
                diff = cur_ho - ho
                costs.append((float(diff.sum()), float(np.sqrt(d.n * np.var(diff))), name,
                              fit_r, ho))
            if not costs:
                break
            cost, se, name, fit_r, ho = min(costs, key=lambda c: c[0])
            drop = not (cost > min_gain and cost > min_z * se)
            candidates.append({"round": "backward", "name": name, "delta_elpd": cost,
                               "se": se, "kept": not drop,
                               "note": ("dropped: more effects kept than max_effects, "
                                        "this the weakest" if once and np.isinf(min_gain)
                                        else "dropped: the other effects explain what it did"
                                        if drop else "kept: its removal costs more than "
                                        "the keep rule")})
            self.say(f"backward: removing {name} costs {cost:+.1f} ± {se:.1f}"
                     + (" -> dropped" if drop else ""))
            if not drop:
                final = {c[2]: (c[0], c[1]) for c in costs}
                kept = [(k, *final.get(k, (delta, s))) for k, delta, s in kept]
                break
            kept = [k for k in kept if k[0] != name]
            current, cur_ho = fit_r, ho
            if once:
                break
        return current, cur_ho, kept

    def refit(self, effects, starts):
        """Fit the model with ``effects`` from ``starts`` and a replant (None if infeasible)."""
        d, path = self.d, self.path
        try:
            fit_e = fit_joint(d, effects, starts, path=path, **self.kw)
        except ValueError:
            return None
        fresh = replant(d, fit_e, self.fittable, path, self.seed)
        if fresh is not None:
            try:
                alt = fit_joint(d, effects, fresh, path=path, **self.kw)
                if alt.loglik > fit_e.loglik:
                    fit_e = alt
            except ValueError:
                pass
        return fit_e

    def fit(self, current, name):
        """Fit ``current`` plus effect ``name``; return the fit (or None) and a note."""
        eff = tuple(sorted(set(current.effects) | {name}, key=term_order))
        starts = start_for(self.d, current, eff, self.path)
        if not starts:
            return None, "no starting point"
        fit_e = self.refit(eff, starts)
        if fit_e is None:
            return None, f"no feasible starting point for the model with {list(eff)}"
        return fit_e, None

    def try_effect(self, current, cur_ho, name, rnd):
        """Score effect ``name`` on top of ``current``: ``(candidate entry, trial or None)``.

        Parameters
        ----------
        rnd : int
            The round of the search.
        """
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
