"""Figures and ``summary.md`` of an output folder, and the folder read back (``docs/cli.md``)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from ._validate import check_choice
from .commands import load, with_results
from .exceptions import InputError
from .io.results import MARKER, read_document, read_marker, write_file
from .lbl.em.pol_sensitivity import POL_GRID, survey_pol_sensitivity
from .plots import bayes as bayes_plots
from .plots import lbl as lbl_plots
from .plots import navigate as nav_plots
from .plots import survey_in as survey_in_plots
from .plots.diagnose import write_figures as write_diagnosis_figures

__all__ = ["POL_GRID", "comparison_figures", "demo_markdown", "diagnosis_figures",
           "fit_figures", "load_output", "locate_figures", "navigation_figures",
           "posterior_figures", "write_figures"]


def _save(fig, path, dpi=110):
    try:
        return write_file(path, lambda tmp: fig.savefig(tmp, dpi=dpi))
    finally:
        plt.close(fig)


def write_figures(result, out_dir, *, beacon=None, truth=None, general=True,
                  sensitivity=None) -> list:
    """Write every figure that applies to ``result`` as PNG files.

    Parameters
    ----------
    result : object
        The result type of a command (:data:`bayes_mpem.commands.COMMANDS`), drawn by
        that command's ``figures``; one with nothing to draw writes no figure.
    out_dir : str or pathlib.Path
        Created if missing.
    beacon : str, optional
        Beacon of a fit's single-beacon figures (the paper's Figs. 7, 9-12; default the
        last fitted beacon, as the paper's beacon 4).
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
    name = f"{type(result).__module__.removeprefix('bayes_mpem.')}:{type(result).__qualname__}"
    for command in with_results().values():
        if command.result == name:
            return load(command.figures)(result, out, beacon=beacon, truth=truth,
                                         general=general, sensitivity=sensitivity)
    kinds = [c.result.partition(":")[2] for c in with_results().values()]
    raise TypeError(f"result: expected a {', '.join(kinds[:-1])} or {kinds[-1]}, got "
                    f"{type(result).__name__}")


# The figures of each result type (named in commands.COMMANDS): the arguments of
# write_figures (``out`` a pathlib.Path); each returns the paths it wrote.
def fit_figures(result, out, *, beacon=None, truth=None, general=True, sensitivity=None) -> list:
    """Write the paper's figures of a :class:`~bayes_mpem.lbl.survey.fitting.SurveyFit`."""
    if not result.results:
        return []
    b = check_choice("beacon", beacon or list(result.results)[-1], sorted(result.results))
    if sensitivity is None and general:
        sensitivity = survey_pol_sensitivity(result, b)
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


def posterior_figures(result, out, *, truth=None, **_) -> list:
    """Write the intervals, traces, pairs and class uncertainty of a posterior."""
    if not result.results:
        return []
    paths = [_save(bayes_plots.plot_intervals(result, truth=truth), out / "intervals.png")]
    for b, r in result.results.items():
        paths.append(_save(bayes_plots.plot_trace(r), out / f"trace_{b}.png", dpi=90))
        paths.append(_save(bayes_plots.plot_pair(r), out / f"pair_{b}.png", dpi=90))
        paths.append(_save(bayes_plots.plot_class_uncertainty(result, b),
                           out / f"classes_{b}.png"))
    return paths


def comparison_figures(result, out, **_) -> list:
    """Write ``compare.png``, equal against learned priors."""
    if not result.results:
        return []
    return [_save(bayes_plots.plot_prior_comparison(result), out / "compare.png")]


def diagnosis_figures(result, out, **_) -> list:
    """Write the figures of a diagnosis (:func:`bayes_mpem.plots.diagnose.write_figures`)."""
    return list(write_diagnosis_figures(result, out).values())


def locate_figures(result, out, *, truth=None, **_) -> list:
    """Write the map and residuals of a located survey; an array's speed and gradients too."""
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
        if (result.summary.get("gradients") or {}).get("series"):
            paths.append(_save(survey_in_plots.plot_gradients(result, truth=truth),
                               out / "gradients.png"))
    return paths


def navigation_figures(result, out, *, truth=None, **_) -> list:
    """Write ``nav_track.png``, ``nav_ranges.png`` and ``nav_correction.png``."""
    return [_save(nav_plots.plot_nav_track(result, truth=truth), out / "nav_track.png"),
            _save(nav_plots.plot_nav_ranges(result), out / "nav_ranges.png"),
            _save(nav_plots.plot_nav_correction(result, truth=truth),
                  out / "nav_correction.png")]


def demo_markdown(simulation, fit, paper, out_dir, figures, *, seed, posterior=None,
                  comparison=None, warnings=()) -> str:
    """Return the ``summary.md`` of ``bayes-mpem demo``.

    Parameters
    ----------
    fit, paper : SurveyFit
        The mixture EM's and the paper's EM's fits.
    out_dir : str or pathlib.Path
        The demo's output folder; figure links are relative to it.
    figures : sequence of pathlib.Path
        Every figure written, linked in this order.
    comparison : SurveyComparison, optional
        With ``posterior``: the Bayesian part, when it ran.
    warnings : sequence of str, default ()
        The warnings the run showed.

    Returns
    -------
    str
        Markdown.
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


def load_output(result_dir):
    """Read an output folder of ``bayes-mpem`` back into what its figures draw.

    Parameters
    ----------
    result_dir : str or pathlib.Path
        The output folder of a command with a result type.

    Returns
    -------
    object
        The ``read(result_dir)`` of the first result type whose ``folder`` entry the
        folder matches (:data:`bayes_mpem.commands.COMMANDS`): never a fit again.

    Raises
    ------
    FileNotFoundError
        When a needed file is missing.
    bayes_mpem.InputError
        When the files do not fit together, or are of no known kind.
    """
    d = Path(result_dir)
    commands = with_results()
    kinds = " | ".join(commands)
    if d.is_file():
        raise InputError(f"{d}: a file; expected the output folder of 'bayes-mpem {kinds}' "
                         "('bayes-mpem stream' writes JSON lines, which have no figures)")
    if (d / MARKER).exists():  # valid JSON, and every data file of the run there (figures
        marker = read_marker(d, check=False)  # are drawn again from the data: not needed)
        files = marker.get("files", [])
        if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
            raise InputError(f"{d / MARKER}: files: expected a list of file names, got "
                             f"{str(files)[:60]!r}; was it edited? Run the command again")
        missing = [f for f in files if not f.endswith(".png")
                   and not (d / f).exists()]
        if missing:
            raise InputError(f"{d / MARKER}: lists {', '.join(missing[:5])}, missing: the folder "
                             "is not a complete output")
    seen = {}
    for command in commands.values():
        marker, keys = command.folder
        if not (d / marker).exists():
            continue
        doc = seen[marker] if marker in seen else read_document(d / marker)
        if all(k in doc for k in keys):
            return load(command.result).read(d)
        seen[marker] = doc
    if MARKER in seen and set(seen[MARKER]) <= {"files", "non_finite"}:  # a bare marker
        raise InputError(f"{d / MARKER}: lists the files of a run and holds no result (a folder "
                         f"of 'bayes-mpem simulate', or of figures); expected the output folder "
                         f"of 'bayes-mpem {kinds}'")
    if seen:
        raise InputError(f"{d / MARKER}: of no known kind (no 'beacons_table' or 'transponders'; "
                         f"not the summary of 'bayes-mpem {kinds}'); it was written by another "
                         "program or an older bayes_mpem: run the command again")
    markers = sorted({c.folder[0] for c in commands.values()})
    if d.is_dir() and any(d.glob("*.jsonl")):
        markers.append("this folder holds JSON lines: 'bayes-mpem stream' answers have no "
                       "figures")
    raise FileNotFoundError(f"{d / 'summary.json'}: not found; expected the output folder of "
                            f"'bayes-mpem {kinds}' (one of "
                            f"{', '.join(markers)})")
