"""Fit every beacon of a survey and write the results."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..._rng import RNGLike, as_generator
from ..._validate import check_choice
from ...io.results import write_json, write_table, writing
from ...io.survey import Survey
from ...io.table_files import TABLE_FORMATS
from ..em.em_paper import fit_paper_em
from ..em.em_result import check_options
from ..em.path_choice import AUTO, check_path_choice, choose_path
from .model_checks import check_fit, checks_record, warn_misfit
from .slips import flag_impossible, load_checked
from .survey import beacons_table, check_min_pings, classified_table, non_finite, over_beacons

METHODS = ("mixture", "paper")


@dataclass(frozen=True)
class SurveyFit:
    """Fits of every beacon of a survey.

    Attributes
    ----------
    survey : Survey
    results : dict of str to EMResult
    skipped : dict of str to str
        Beacons left unfitted, with the reason.
    method : str
    options : dict
        The options passed to the per-beacon fits.
    path_choices : dict of str to PathChoice
        Per fitted beacon, the multipath geometry used.
    checks : dict of str to list
        Per fitted beacon, its model checks (empty for a refracted fit).
    """

    survey: Survey
    results: dict
    skipped: dict
    method: str
    options: dict = field(default_factory=dict)
    path_choices: dict = field(default_factory=dict)
    checks: dict = field(default_factory=dict)

    def classified(self) -> pd.DataFrame:
        """Every input row with ``p_dp``, ``p_mp``, ``p_ol``, ``label`` and ``reason``.

        Returns
        -------
        pandas.DataFrame
            Same rows and order as the input; labels ``dp``, ``mp``, ``ol``, ``no_reply``,
            ``skipped``.
        """
        out = classified_table(
            self.survey, {bid: (r.rows, r.resp) for bid, r in self.results.items()},
            self.skipped)
        return flag_impossible(out, self.survey)  # ranges shorter than any path: a reason

    def summary(self) -> dict:
        """JSON-ready summary: per-beacon parameters, counts, skipped beacons."""
        beacons = {}
        for bid, res in self.results.items():
            d = res.to_dict()
            depth = float(self.survey.beacons.loc[bid, "depth"])
            d["beacon_depth"] = depth
            d["plane_depth"] = depth - res.d0
            d["n_no_reply"] = int(np.sum(self.survey.no_reply & (self.survey.beacon == bid)))
            if bid in self.path_choices:
                d["path_choice"] = self.path_choices[bid].to_dict()
            if bid in self.checks:
                d["model_checks"] = checks_record(self.checks[bid], self.method)
            beacons[bid] = d
        return {
            "method": self.method,
            "beacons": beacons,
            "beacons_table": beacons_table(self.survey),
            "skipped": dict(self.skipped),
            "n_rows": len(self.survey),
            "n_no_reply": int(self.survey.no_reply.sum()),
            "pings": self.survey.pings_source,
            "beacons_file": self.survey.beacons_source,
            "options": {k: v for k, v in self.options.items() if k != "rng"},
        }

    def to_dict(self) -> dict:
        """Return the content of ``summary.json`` (the same as :meth:`summary`)."""
        return self.summary()

    def table(self) -> pd.DataFrame:
        """Per-beacon table in the spirit of the paper's Table II.

        Returns
        -------
        pandas.DataFrame
            ``beacon``, ``d0_m``, ``sigma_mp_m``, ``beacon_depth_m``, ``plane_depth_m``,
            ``sigma_dp_m``, ``dp``, ``mp``, ``ol``, ``n``, ``converged``, ``path``, ``path_margin``.
        """
        rows = []
        for bid, res in self.results.items():
            depth = float(self.survey.beacons.loc[bid, "depth"])
            fr = res.class_fractions
            rows.append({"beacon": bid, "d0_m": res.d0, "sigma_mp_m": res.sigma_mp,
                         "beacon_depth_m": depth, "plane_depth_m": depth - res.d0,
                         "sigma_dp_m": res.sigma_dp, **fr, "n": res.n,
                         "converged": res.converged, "path": res.path,
                         "path_margin": (self.path_choices[bid].margin
                                         if bid in self.path_choices else float("nan"))})
        return pd.DataFrame(rows)

    def format_table(self) -> str:
        """Format the :meth:`table` as aligned text for a terminal."""
        t = self.table()
        lines = [f"{'beacon':>6} {'d0 (m)':>11} {'sigma_MP (m)':>12} {'depth (m)':>10} "
                 f"{'plane (m)':>9} {'DP':>6} {'MP':>6} {'OL':>6} {'n':>6} {'path':>8} "
                 f"{'margin':>7}"]
        for r in t.itertuples():
            lines.append(f"{r.beacon:>6} {r.d0_m:11.1f} {r.sigma_mp_m:12.2f} "
                         f"{r.beacon_depth_m:10.1f} {r.plane_depth_m:9.1f} {r.dp:6.3f} "
                         f"{r.mp:6.3f} {r.ol:6.3f} {r.n:6d} {r.path:>8} {r.path_margin:7.0f}")
        for bid, why in self.skipped.items():
            lines.append(f"{bid:>6} skipped: {why}")
        return "\n".join(lines)

    def write(self, out_dir, *, table_format: str = "csv") -> dict:
        """Write ``classified.csv``, ``history.json`` and, last, ``summary.json`` to ``out_dir``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
        table_format : {"csv", "parquet"}, default "csv"

        Returns
        -------
        dict
            Paths written, keyed ``summary``, ``classified`` and ``history``.
        """
        check_choice("table_format", table_format, TABLE_FORMATS)
        with writing(out_dir) as out:
            return {"classified": write_table(out / f"classified.{table_format}",
                                              self.classified()),
                    "history": write_json(out / "history.json", self.history(as_arrays=True),
                                          indent=None, numpy=True),
                    "summary": write_json(out / "summary.json", self.summary())}

    def history(self, *, as_arrays: bool = False) -> dict:
        """Per beacon: every iteration's parameters and the first E-step's probabilities.

        Parameters
        ----------
        as_arrays : bool, default False
            Give ``first_resp`` as a NumPy array instead of nested lists.

        Returns
        -------
        dict
            ``{beacon: {"history": {name: [..]}, "first_resp": [[p_dp, p_mp, p_ol], ..]}}``.
        """
        def first(r):
            rounded = np.round(r.first_resp, 3)
            return rounded if as_arrays else rounded.tolist()

        return {bid: {"history": {k: np.asarray(v).tolist() for k, v in r.history.items()},
                      "first_resp": first(r)}
                for bid, r in self.results.items()}

    @classmethod
    def read(cls, folder) -> SurveyFit:
        """Read a fit back from the folder :meth:`write` wrote, never by fitting again.

        Without ``history.json``, each beacon gets a one-entry history. A missing file is a
        ``FileNotFoundError``, files that do not fit together an ``InputError``.

        Parameters
        ----------
        folder : str or pathlib.Path
            The output folder.

        Returns
        -------
        SurveyFit
        """
        from pathlib import Path

        from ...io.results import MARKER, read_document
        from ..em.em_result import EMResult
        from ..em.path_choice import choices_from_summary
        from .folder import numbers, survey_and_classes, together

        d = Path(folder)
        summary = read_document(d / MARKER)
        survey, probs, _ = survey_and_classes(d, summary)
        hist = read_document(d / "history.json") if (d / "history.json").exists() else {}

        def rebuild():
            results = {}
            for b, s in summary["beacons"].items():
                numbers(d, s, ("d0", "sigma_mp", "sigma_dp"), f"beacons.{b}")
                rows = survey.for_beacon(b).rows
                h = hist.get(b, {})
                history = {k: np.asarray(v) for k, v in h.get("history", {}).items()} or {
                    "d0": np.array([s["d0"]]), "sigma_mp": np.array([s["sigma_mp"]])}
                results[b] = EMResult(
                    beacon=b, method=s["method"], path=s["path"], d0=s["d0"],
                    sigma_mp=s["sigma_mp"], sigma_dp=s["sigma_dp"], weights=s["weights"],
                    resp=probs[rows], rows=rows, n_iter=s["iterations"],
                    converged=s["converged"], loglik=s.get("loglik"), history=history,
                    first_resp=np.asarray(h["first_resp"]) if "first_resp" in h else probs[rows],
                    settings=s.get("settings", {}), d0_se=s.get("d0_se"))
            return cls(survey=survey, results=results, skipped=summary.get("skipped", {}),
                       method=summary["method"], options=summary.get("options", {}),
                       path_choices=choices_from_summary(summary["beacons"]))

        return together(d, rebuild)


def _non_finite_fit(res) -> list:
    """Names of a fit's values that are not finite (the fit then failed)."""
    doc = {"d0": res.d0, "sigma_mp": res.sigma_mp, "sigma_dp": res.sigma_dp,
           "weights": res.weights, "loglik": res.loglik if res.loglik is not None else 0.0}
    return non_finite(doc) + ([] if np.isfinite(res.resp).all() else ["class probabilities"])


def fit(
    pings,
    beacons=None,
    *,
    method: str = "mixture",
    path: str = AUTO,
    sigma_dp: float | None = None,
    pol: float = 0.05,
    alpha: float = 0.5,
    weights: str = "learned",
    min_pings: int = 30,
    rng: RNGLike = None,
    **kwargs,
) -> SurveyFit:
    """Classify every range and identify each beacon's reflector.

    Parameters
    ----------
    pings : str, pathlib.Path, pandas.DataFrame or Survey
        The pings table (``docs/input.md``), or a loaded survey.
    beacons : str, pathlib.Path or pandas.DataFrame, optional
        The beacons table (not needed when ``pings`` is a Survey).
    method : {"mixture", "paper"}
        The density-mixture EM (default) or the paper's EM.
    path : {"auto", "triangle", "double"}
        Multipath geometry: one reflected leg, both, or (default) per beacon the likelier.
    sigma_dp : float, optional
        Direct-path scatter (m); estimated if omitted.
    pol, alpha : float
        The paper's EM knobs (``method="paper"`` only).
    weights : {"learned", "equal"}
        Mixing weights of the mixture EM.
    min_pings : int, default 30
        Beacons with fewer replies are left unfitted.
    rng : None, int or numpy.random.Generator
    **kwargs
        Passed to :func:`~bayes_mpem.lbl.em.em_mixture.fit_mixture_em` or
        :func:`~bayes_mpem.lbl.em.em_paper.fit_paper_em`.

    Returns
    -------
    SurveyFit

    Raises
    ------
    bayes_mpem.exceptions.InputError
        For invalid input (the message names the file, row and column).
    ValueError
        For invalid options.

    Warns
    -----
    SkippedBeaconWarning, PathChoiceWarning, ModelCheckWarning
        A beacon left unfitted; a forced ``path`` clearly worse than the other; ranges the
        fitted model does not describe.

    Examples
    --------
    >>> import bayes_mpem
    >>> sim = bayes_mpem.simulate_survey("abe58", rng=3)
    >>> res = bayes_mpem.fit(sim.survey, rng=0)
    >>> sorted(res.results)
    ['1', '2', '3', '4']
    """
    check_choice("method", method, METHODS)
    check_path_choice(path)
    check_min_pings(min_pings)
    check_options(weights=weights, pol=pol, alpha=alpha, sigma_dp=sigma_dp)
    survey = load_checked(pings, beacons)  # load_survey, naming the usual slips (slips.py)
    gen = as_generator(rng)
    choices = {}

    def fit_one(data):
        # stacklevel 5: choose_path, fit_one, over_beacons, fit, then fit's caller
        if method == "mixture":
            choice = choose_path(data, path, sigma_dp=sigma_dp, weights=weights, rng=gen,
                                 stacklevel=5, **kwargs)
            choices[data.beacon] = choice
            return choice.fit
        choice = choose_path(data, path, sigma_dp=sigma_dp, rng=gen, fit_warnings=False,
                             stacklevel=5)
        choices[data.beacon] = choice
        return fit_paper_em(data, path=choice.path, sigma_dp=sigma_dp, pol=pol, alpha=alpha,
                            **kwargs)

    results, skipped = over_beacons(survey, min_pings, fit_one, check=_non_finite_fit)
    checks = {}
    for bid, res in results.items():
        if kwargs.get("ssp") is None:  # the checks predict straight rays
            checks[bid] = check_fit(survey.for_beacon(bid), res)
            warn_misfit(bid, checks[bid], method=method, stacklevel=2)
    options = {"path": path, "sigma_dp": sigma_dp, "min_pings": min_pings, **kwargs}
    if method == "mixture":
        options["weights"] = weights
    else:
        options.update(pol=pol, alpha=alpha)
    return SurveyFit(survey=survey, results=results, skipped=skipped, method=method,
                     options=options, path_choices=choices, checks=checks)
