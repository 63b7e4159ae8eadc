"""Figures and summaries written to an output folder, and reading such a folder back."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from ._validate import check_choice
from .exceptions import InputError
from .io.results import MARKER, read_marker, write_file
from .io.survey import load_survey
from .io.table_files import frame_as_text, read_table_file
from .io.tables import RESERVED_COLUMNS
from .lbl.diagnosis.result import Diagnosis, DiagnosisRecord
from .lbl.em.em_result import EMResult
from .lbl.em.path_choice import choices_from_summary
from .lbl.em.pol_sensitivity import POL_GRID, survey_pol_sensitivity
from .lbl.navigate.result import Navigation, NavigationRecord
from .lbl.survey.comparison import SurveyComparison
from .lbl.survey.fitting import SurveyFit
from .lbl.survey.sampling import SurveyPosterior, posterior_file
from .mixture.densities import CLASSES
from .plots import bayes as bayes_plots
from .plots import lbl as lbl_plots
from .plots import navigate as nav_plots
from .plots import survey_in as survey_in_plots
from .plots.diagnose import write_figures as write_diagnosis_figures
from .survey_in.result import SurveyInResult

__all__ = ["FOLDER_KINDS", "POL_GRID", "demo_markdown", "figure_beacon", "folder_kind",
           "load_output", "write_figures"]

_ADDED = set(RESERVED_COLUMNS)


def _save(fig, path, dpi=110):
    try:
        return write_file(path, lambda tmp: fig.savefig(tmp, dpi=dpi))
    finally:
        plt.close(fig)


def figure_beacon(survey_fit, beacon=None) -> str:
    """Return the beacon of a fit's single-beacon figures (the paper's Figs. 7, 9-12).

    Parameters
    ----------
    survey_fit : SurveyFit
        With at least one fitted beacon.
    beacon : str, optional
        Default: the last fitted beacon (the paper uses its beacon 4).

    Raises
    ------
    ValueError
        When ``beacon`` was not fitted.
    """
    b = beacon or list(survey_fit.results)[-1]
    return check_choice("beacon", b, sorted(survey_fit.results))


def write_figures(result, out_dir, *, beacon=None, truth=None, general=True,
                  sensitivity=None) -> list:
    """Write every figure that applies to ``result`` as PNG files.

    Parameters
    ----------
    result : SurveyFit, SurveyPosterior, SurveyComparison, Diagnosis, SurveyInResult or Navigation
        Or the record of one read back by :func:`load_output` (a
        :class:`~bayes_mpem.lbl.navigate.result.NavigationRecord` for a navigation).
        A result with nothing to draw (no fitted beacon or transponder) writes no
        figure. A navigation writes
        ``nav_track.png``, ``nav_ranges.png``
        and ``nav_correction.png``.
    out_dir : str or pathlib.Path
        Created if missing.
    beacon : str, optional
        Beacon of the single-beacon figures of a fit (:func:`figure_beacon`).
    truth : dict or pandas.DataFrame, optional
        ``Simulation.truth``, marked where a figure can show it (fits, posteriors);
        for a navigation, the true track (``DiveSimulation.true_track``); for a
        GNSS-A array, a campaign's ``truth.json`` (the true positions and sound speed).
    general : bool, default True
        Fits: also write the method-independent figures (Figs. 1, 5, 8 and 12).
    sensitivity : dict, optional
        Fits: :func:`~bayes_mpem.lbl.em.pol_sensitivity.survey_pol_sensitivity`
        of the figure beacon, drawn as the paper's Fig. 12; computed here
        (seconds) when not given.

    Raises
    ------
    TypeError
        For another kind of result.
    ValueError
        When ``beacon`` was not fitted.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if isinstance(result, SurveyFit):
        if sensitivity is None and general and result.results:
            sensitivity = survey_pol_sensitivity(result, figure_beacon(result, beacon))
        return _fit_figures(result, out, beacon=beacon, truth=truth, general=general,
                            sensitivity=sensitivity)
    if isinstance(result, SurveyPosterior):
        return _posterior_figures(result, out, truth=truth)
    if isinstance(result, (SurveyComparison, ComparisonRecord)):
        if not result.results:
            return []
        return [_save(bayes_plots.plot_prior_comparison(result), out / "compare.png")]
    if isinstance(result, (Diagnosis, DiagnosisRecord)):
        return list(write_diagnosis_figures(result, out).values())
    if isinstance(result, SurveyInResult):
        if not result.summary.get("transponders"):
            return []
        paths = [_save(survey_in_plots.plot_survey_map(result), out / "survey_map.png"),
                 _save(survey_in_plots.plot_residuals(result), out / "residuals.png"),
                 _save(survey_in_plots.plot_residual_histogram(result),
                       out / "residual_histogram.png")]
        if "array_centre" in result.summary:  # GNSS-A: the array, its sound speed, per transponder
            truth = truth if isinstance(truth, dict) and "array_centre" in truth else None
            paths += [_save(survey_in_plots.plot_array_map(result, truth=truth),
                            out / "array_map.png"),
                      _save(survey_in_plots.plot_sound_speed(result, truth=truth),
                            out / "sound_speed.png"),
                      _save(survey_in_plots.plot_residuals_by_transponder(result),
                            out / "residuals_by_transponder.png")]
        return paths
    if isinstance(result, (Navigation, NavigationRecord)):
        return [_save(nav_plots.plot_nav_track(result, truth=truth), out / "nav_track.png"),
                _save(nav_plots.plot_nav_ranges(result), out / "nav_ranges.png"),
                _save(nav_plots.plot_nav_correction(result, truth=truth),
                      out / "nav_correction.png")]
    raise TypeError(f"result: expected a SurveyFit, SurveyPosterior, SurveyComparison, "
                    f"Diagnosis, SurveyInResult or Navigation, got {type(result).__name__}")


def _fit_figures(result, out, *, beacon, truth, general, sensitivity):
    if not result.results:
        return []
    b = figure_beacon(result, beacon)
    r = result.results[b]
    t = None if truth is None else truth[b]
    paths = []
    if general:
        paths.append(_save(lbl_plots.plot_ranges(result.survey), out / "fig01_ranges.png"))
        paths.append(_save(lbl_plots.plot_track(result.survey), out / "fig05_track.png"))
        paths.append(_save(lbl_plots.plot_colormap(), out / "fig08_colormap.png"))
        if sensitivity is not None:
            paths.append(_save(lbl_plots.plot_pol_sensitivity(sensitivity, truth=t),
                               out / f"fig12_pol_sensitivity_{b}.png"))
    figs = [(lbl_plots.plot_classification(result, b, iteration="first"),
             f"fig07_first_iteration_{b}.png"),
            (lbl_plots.plot_classification(result, b), f"fig09_last_iteration_{b}.png"),
            (lbl_plots.plot_convergence(r, truth=t), f"fig10_11_convergence_{b}.png"),
            (lbl_plots.plot_survey_classification(result), "fig13_classification.png"),
            (lbl_plots.plot_table_ii(result), "table2.png")]
    return paths + [_save(fig, out / name) for fig, name in figs]


def _posterior_figures(result, out, *, truth):
    if not result.results:
        return []
    paths = [_save(bayes_plots.plot_intervals(result, truth=truth), out / "intervals.png")]
    for b, r in result.results.items():
        paths.append(_save(bayes_plots.plot_trace(r), out / f"trace_{b}.png", dpi=90))
        paths.append(_save(bayes_plots.plot_pair(r), out / f"pair_{b}.png", dpi=90))
        paths.append(_save(bayes_plots.plot_class_uncertainty(result, b),
                           out / f"classes_{b}.png"))
    return paths


def demo_markdown(simulation, fit, paper, out_dir, figures, *, seed, posterior=None,
                  comparison=None, warnings=()) -> str:
    """Return the ``summary.md`` of ``bayes-mpem demo``.

    Parameters
    ----------
    simulation : Simulation
        The simulated survey (its ``survey`` and ``truth``).
    fit, paper : SurveyFit
        The mixture EM's and the paper's EM's fits.
    out_dir : str or pathlib.Path
        The demo's output folder; figure links are relative to it.
    figures : sequence of pathlib.Path
        Every figure written, linked in this order.
    seed : int
    posterior : SurveyPosterior, optional
    comparison : SurveyComparison, optional
        With ``posterior``: the Bayesian part, when it ran.
    warnings : sequence of str, default ()
        The warnings the run showed, listed under "Warnings".

    Returns
    -------
    str
        Markdown, ending with a newline.
    """
    sim = simulation
    md = ["# bayes-mpem demo", "",
          f"Simulated ABE58-like survey (seed {seed}): {len(sim.survey)} pings to "
          f"{len(sim.truth)} beacons. Truth: the sea surface, i.e. d0 = beacon depth.", "",
          "## Table II, mixture EM", "", lbl_plots.table_ii_markdown(fit, truth=sim.truth), "",
          "## Table II, the paper's EM (Pol = 0.05, alpha = 0.5)", "",
          lbl_plots.table_ii_markdown(paper, truth=sim.truth), ""]
    if posterior is not None:
        md += ["## Posterior (learned priors)", "", "```", posterior.format_table(), "```", "",
               "![intervals](bayes/intervals.png)", "",
               "## Equal against learned priors", "", "```", comparison.format_table(), "```",
               "", "![compare](compare/compare.png)", ""]
    listed = [f"- {' '.join(w.split())}" for w in warnings]  # one line each
    md += ["## Warnings", ""] + (listed or ["None."]) + [""]
    out = Path(out_dir)
    md += ["## Figures", ""] + [f"![{p.stem}]({p.relative_to(out).as_posix()})"
                                for p in figures]
    return "\n".join(md) + "\n"


@dataclass(frozen=True)
class ComparisonRecord:
    """A prior comparison read back from ``compare.json``: what its figure draws.

    Attributes
    ----------
    results : dict
        Per beacon, a namespace with ``elpd_diff``, ``elpd_diff_se``, ``shifts``
        and ``learned.em.d0`` (as :class:`~bayes_mpem.lbl.bayes.loo.PriorComparison`).
    """

    results: dict


#: Output folder kinds ``bayes-mpem plot`` reads, tried in order: ``(kind, file, test,
#: loader)``; a folder is of the first kind whose ``file`` exists and whose JSON passes
#: ``test``; ``loader(folder, document)`` returns what :func:`write_figures` draws.
FOLDER_KINDS: list = []


def folder_kind(kind: str, marker: str, test=None):
    """Register a loader of an output folder kind for :func:`load_output` (a decorator).

    Parameters
    ----------
    kind : str
        Its name, for messages (``"fit"``, ``"locate"``, ...).
    marker : str
        The JSON file that identifies the folder (``"summary.json"``, ...).
    test : callable, optional
        ``test(document) -> bool``: the folder is of this kind (default: any).

    Returns
    -------
    callable
        The decorator; it returns the loader unchanged.
    """
    def register(loader):
        FOLDER_KINDS.append((kind, marker, test or (lambda doc: True), loader))
        return loader
    return register


def load_output(result_dir):
    """Read an output folder of ``bayes-mpem`` back into what its figures draw.

    Parameters
    ----------
    result_dir : str or pathlib.Path
        The output folder of ``fit``, ``sample``, ``compare``, ``diagnose``,
        ``locate`` or ``navigate`` (:data:`FOLDER_KINDS`).

    Returns
    -------
    SurveyFit, SurveyPosterior, ComparisonRecord, DiagnosisRecord, SurveyInResult, NavigationRecord
        Rebuilt from the files (never by fitting again). A fit without ``history.json`` gets a
        one-entry history; a posterior's ``em`` is a namespace of the EM
        start's parameters.

    Raises
    ------
    FileNotFoundError
        When a needed file is missing.
    bayes_mpem.InputError
        When the files do not fit together, or are of no known kind.
    """
    d = Path(result_dir)
    kinds = " | ".join(k for k, *_ in FOLDER_KINDS)
    if d.is_file():
        raise InputError(f"{d}: a file; expected the output folder of 'bayes-mpem {kinds}' "
                         "('bayes-mpem stream' writes JSON lines, which have no figures)")
    if (d / MARKER).exists():  # valid JSON, and every data file of the run there (figures
        marker = read_marker(d, check=False)  # are drawn again from the data: not needed)
        missing = [f for f in marker.get("files", []) if not f.endswith(".png")
                   and not (d / f).exists()]
        if missing:
            raise InputError(f"{d / MARKER}: lists {', '.join(missing[:5])}, missing: the folder "
                             "is not a complete output")
    seen = {}
    for kind, marker, test, loader in FOLDER_KINDS:
        path = d / marker
        if not path.exists():
            continue
        doc = _read_json(path)
        if not isinstance(doc, dict):
            raise InputError(f"{path}: expected a JSON object, got {type(doc).__name__}")
        if test(doc):
            return loader(d, doc)
        seen[marker] = doc
    if MARKER in seen and set(seen[MARKER]) <= {"files", "non_finite"}:  # a bare marker
        raise InputError(f"{d / MARKER}: lists the files of a run and holds no result (a folder "
                         f"of 'bayes-mpem simulate', or of figures); expected the output folder "
                         f"of 'bayes-mpem {kinds}'")
    if seen:
        raise InputError(f"{d / MARKER}: of no known kind (no 'beacons_table' or 'transponders'; "
                         f"not the summary of 'bayes-mpem {kinds}'); it was written by another "
                         "program or an older bayes_mpem: run the command again")
    markers = sorted({m for _, m, _, _ in FOLDER_KINDS})
    if d.is_dir() and any(d.glob("*.jsonl")):
        markers.append("this folder holds JSON lines: 'bayes-mpem stream' answers have no "
                       "figures")
    raise FileNotFoundError(f"{d / 'summary.json'}: not found; expected the output folder of "
                            f"'bayes-mpem {kinds}' (one of "
                            f"{', '.join(markers)})")


def _read_json(path):
    try:
        return json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not valid JSON ({exc}); the file is damaged") from None


def _classified(d, summary):
    """Read the classified table of an output folder as text, checked against its summary."""
    files = summary.get("files", [])
    name = next((f for f in ("classified.parquet", "classified.csv") if f in files),
                "classified.csv")
    frame = read_table_file(d / name, str(d / name), "classified table").frame
    n_rows = summary.get("n_rows")
    if n_rows is not None and len(frame) != n_rows:
        raise InputError(f"{d / name}: {len(frame)} rows, but {d / MARKER} says n_rows = "
                         f"{n_rows}: the table is truncated or from another run")
    missing = [c for c in ("p_dp", "p_mp", "p_ol", "label") if c not in frame.columns]
    if missing:
        raise InputError(f"{d / name}: missing column(s) {', '.join(missing)}; not a "
                         "classified table of 'bayes-mpem fit', 'sample' or 'navigate'")
    return frame_as_text(frame) if name.endswith(".parquet") else frame


def _fit_or_sample(d, summary):
    classified = _classified(d, summary)
    table = classified[[c for c in classified.columns if c not in _ADDED]]
    beacons = pd.DataFrame([{"beacon": b, **v} for b, v in summary["beacons_table"].items()])
    survey = load_survey(table, beacons)
    num = {}
    for c in sorted(_ADDED - {"label", "reason"}):
        if c in classified.columns:
            num[c] = pd.to_numeric(classified[c].replace("", np.nan), errors="coerce").to_numpy()
            bad = np.flatnonzero(np.isnan(num[c]) & (classified[c] != "").to_numpy()
                                 | (num[c] < 0) | (num[c] > 1))
            if bad.size:
                raise InputError(f"{d} classified table, row {int(bad[0]) + 1}, column {c!r}: "
                                 f"expected a probability, got {classified[c].iloc[bad[0]]!r}")
    probs = np.column_stack([num["p_" + c] for c in CLASSES])
    return survey, probs, num


def _together(d, load, *args):
    """Return ``load(*args)``; a key or a type missing in the files is an InputError."""
    try:
        return load(*args)
    except (KeyError, TypeError, IndexError) as exc:
        raise InputError(f"{d / MARKER}: the output files do not fit together "
                         f"({type(exc).__name__}: {exc})") from None


@folder_kind("fit", "summary.json", lambda doc: "beacons_table" in doc and "method" in doc)
def _folder_fit(d, summary):
    survey, probs, _ = _fit_or_sample(d, summary)
    return _together(d, _load_fit, d, summary, survey, probs)


@folder_kind("sample", "summary.json", lambda doc: "beacons_table" in doc and "priors" in doc)
def _folder_sample(d, summary):
    survey, probs, num = _fit_or_sample(d, summary)
    return _together(d, _load_posterior, d, summary, survey, probs, num)


@folder_kind("locate", "summary.json", lambda doc: "transponders" in doc)
def _folder_locate(d, summary):
    path = d / "classified.csv"
    if not path.exists():
        raise FileNotFoundError(f"{path}: not found; 'bayes-mpem locate' writes it")
    cls = pd.read_csv(path, keep_default_na=False, na_values=[""],
                      dtype={"transponder": str, "label": str, "reason": str})
    cls["transponder"] = cls["transponder"].fillna("")
    missing = [c for c in ("residual_ms", "azimuth_deg", "east", "north", "time")
               if c not in cls.columns]
    if missing:
        raise InputError(f"{path}: no column(s) {missing}; it was written by an older "
                         "bayes_mpem: run 'bayes-mpem locate' again")
    return SurveyInResult(summary=summary, classified=cls)


@folder_kind("compare", "compare.json")
def _folder_compare(d, doc):
    results = {}
    for b, r in doc["beacons"].items():
        if "em_d0" not in r:
            raise InputError(f"{d / 'compare.json'}: no 'em_d0'; it was written by an older "
                             "bayes_mpem: run 'bayes-mpem compare' again")
        results[b] = SimpleNamespace(
            elpd_diff=r["elpd_diff"], elpd_diff_se=r["elpd_diff_se"], shifts=r["shifts"],
            learned=SimpleNamespace(em=SimpleNamespace(d0=r["em_d0"])))
    return ComparisonRecord(results=results)


@folder_kind("diagnose", "diagnosis.json")
def _folder_diagnose(d, doc):
    path = d / "replies.csv"
    if not path.exists() or "figures" not in doc:
        raise FileNotFoundError(f"{path}: not found; 'bayes-mpem diagnose' writes it (a folder "
                                "of an older bayes_mpem: run it again)")
    return DiagnosisRecord(document=doc, table=pd.read_csv(path, dtype={"beacon": str}))


@folder_kind("navigate", "summary.json",
             lambda doc: "dead_reckoning" in doc and "track" in doc and "beacons_table" in doc)
def _folder_navigate(d, summary):
    path = d / "track.csv"
    if not path.exists():
        raise FileNotFoundError(f"{path}: not found; 'bayes-mpem navigate' writes it")
    track = read_table_file(path, str(path), "track file").frame
    survey, probs, _ = _fit_or_sample(d, summary)
    return _together(d, NavigationRecord.from_tables, summary, survey, track, probs)


def _load_fit(d, summary, survey, probs):
    hist_path = d / "history.json"
    hist = _read_json(hist_path) if hist_path.exists() else {}
    if not isinstance(hist, dict):
        raise InputError(f"{hist_path}: expected a JSON object of beacons, got "
                         f"{type(hist).__name__}")
    results = {}
    for b, s in summary["beacons"].items():
        rows = survey.for_beacon(b).rows
        resp = probs[rows]
        h = hist.get(b, {})
        history = {k: np.asarray(v) for k, v in h.get("history", {}).items()} or {
            "d0": np.array([s["d0"]]), "sigma_mp": np.array([s["sigma_mp"]])}
        first = np.asarray(h["first_resp"]) if "first_resp" in h else resp
        results[b] = EMResult(
            beacon=b, method=s["method"], path=s["path"], d0=s["d0"], sigma_mp=s["sigma_mp"],
            sigma_dp=s["sigma_dp"], weights=s["weights"], resp=resp, rows=rows,
            n_iter=s["iterations"], converged=s["converged"], loglik=s.get("loglik"),
            history=history, first_resp=first, settings=s.get("settings", {}),
            d0_se=s.get("d0_se"))
    return SurveyFit(survey=survey, results=results, skipped=summary.get("skipped", {}),
                     method=summary["method"], options=summary.get("options", {}),
                     path_choices=choices_from_summary(summary["beacons"]))


def _load_posterior(d, summary, survey, probs, num):
    import xarray as xr

    from .lbl.bayes.beacon_sampling import PosteriorResult

    sd = np.column_stack([num["p_" + c + "_sd"] for c in CLASSES])
    results = {}
    for b, s in summary["beacons"].items():
        path = d / posterior_file(b) if "file" not in s else d / Path(s["file"]).name
        if not path.exists():
            raise FileNotFoundError(f"{path}: not found; 'bayes-mpem sample' writes it")
        try:
            tree = xr.open_datatree(path, engine="h5netcdf").load()
        except (OSError, ValueError) as exc:
            raise InputError(f"{path}: not a readable NetCDF file ({exc})") from None
        rows = survey.for_beacon(b).rows
        results[b] = PosteriorResult(
            beacon=b, priors=s["priors"], path=s["path"], idata=tree,
            summary={k: s[k] for k in ("d0", "sigma_mp", "sigma_dp", "weights")},
            tau=s["tau"], ess=s["ess"], ess_bulk=s.get("ess_bulk", {}), rhat=s.get("rhat"),
            class_probs=probs[rows],
            class_probs_sd=sd[rows], rows=rows, em=SimpleNamespace(**s.get("em", {})),
            diagnostics=s.get("diagnostics", {}), ci=s.get("ci", summary.get("ci", 0.95)))
    return SurveyPosterior(survey=survey, results=results, skipped=summary.get("skipped", {}),
                           priors=summary["priors"], ci=summary.get("ci", 0.95),
                           options=summary.get("options", {}),
                           path_choices=choices_from_summary(summary["beacons"]))
