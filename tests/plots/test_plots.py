"""Figures: each function returns a Figure showing what the paper's figure shows."""

import json

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

import bayes_mpem as bm
from bayes_mpem.lbl.em.pol_sensitivity import pol_sensitivity
from bayes_mpem.plots import bayes as bayes_plots
from bayes_mpem.plots.diagnose import running_mean
from bayes_mpem.plots.lbl import (
    plot_classification,
    plot_colormap,
    plot_convergence,
    plot_pol_sensitivity,
    plot_ranges,
    plot_survey_classification,
    plot_table_ii,
    plot_track,
    table_ii_markdown,
)
from bayes_mpem.plots.style import (
    PALETTES,
    class_color,
    class_colors,
    palette_context,
    use_palette,
)
from bayes_mpem.report import load_output, write_figures


@pytest.fixture(scope="module")
def sim():
    return bm.simulate_survey("abe58", rng=0, n_cycles=400)


@pytest.fixture(scope="module")
def paper_fit():
    # the full abe58 survey: the paper's EM finds beacon 4's plane and (as documented)
    # not beacon 1's or 2's, which it flags
    full = bm.simulate_survey("abe58", rng=0)
    with pytest.warns(bm.FitQualityWarning):
        res = bm.fit(full.survey, method="paper", sigma_dp=3.97)
    assert not res.results["4"].flags and res.results["1"].flags
    return res


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _scatter_colors(ax):
    return np.concatenate([c.get_facecolors()[:, :3] for c in ax.collections])


def _legend_texts(legend):
    return [t.get_text() for t in legend.get_texts()] if legend is not None else []


def _has_class_key(fig):
    texts = [t for leg in (*fig.legends, *(ax.get_legend() for ax in fig.axes))
             for t in _legend_texts(leg)]
    return {"direct path", "multipath", "outlier"} <= set(texts)


def test_class_colors_blend_continuously():
    p = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0], [1 / 3, 1 / 3, 1 / 3]])
    rgb = class_colors(p, palette="paper")
    np.testing.assert_allclose(rgb[:3], [[0, 0, 1], [1, 0, 0], [0, 1, 0]])  # DP, MP, OL
    np.testing.assert_allclose(rgb[3], [0.5, 0, 0.5])  # half DP, half MP: purple
    safe = PALETTES["okabe-ito"]
    rgb = class_colors(p)  # the default: colour-blind safe
    np.testing.assert_allclose(rgb[:3], [safe["dp"], safe["mp"], safe["ol"]])
    np.testing.assert_allclose(rgb[3], np.mean([safe["dp"], safe["mp"]], axis=0))


def test_palette_option_and_its_context():
    assert class_color("mp") == PALETTES["okabe-ito"]["mp"]
    with palette_context("paper"):
        assert class_color("mp") == (1.0, 0.0, 0.0)
    assert class_color("mp") == PALETTES["okabe-ito"]["mp"]  # restored
    with pytest.raises(ValueError, match="palette: expected one of"):
        use_palette("rainbow")


def test_fig01_ranges_one_series_per_beacon(sim):
    fig = plot_ranges(sim.survey)
    ax = fig.axes[0]
    assert isinstance(fig, Figure) and len(ax.lines) == 4
    assert sum(len(line.get_xdata()) for line in ax.lines) == int((~sim.survey.no_reply).sum())
    assert _legend_texts(ax.get_legend()) == ["beacon 1", "beacon 2", "beacon 3", "beacon 4"]


def test_fig05_track_shows_beacons(sim):
    ax = plot_track(sim.survey).axes[0]
    assert len(ax.texts) == 4  # beacon labels


def test_fig08_colormap_blends(sim):
    fig = plot_colormap(resolution=100)
    img = fig.axes[0].images[0].get_array()
    inside = img[..., 3] > 0
    rgb = img[..., :3][inside]
    # continuous: many distinct colours, including mixtures of all three channels
    assert len(np.unique(np.round(rgb, 2), axis=0)) > 1000
    assert np.any(np.all(rgb > 0.2, axis=1))


def test_fig07_fig09_first_and_last_iteration(sim, paper_fit):
    first = plot_classification(paper_fit, "4", iteration="first")
    last = plot_classification(paper_fit, "4", iteration="last")
    c_first, c_last = _scatter_colors(first.axes[0]), _scatter_colors(last.axes[0])
    n = paper_fit.results["4"].n
    assert len(c_first) == len(c_last) == n
    # first E-step: hardly any outliers; last: the outliers are drawn in the outlier colour
    def outlier_share(c):
        return np.mean(np.all(np.abs(c - class_color("ol")) < 0.05, axis=1))

    assert outlier_share(c_first) < outlier_share(c_last)
    assert "first E-step" in first.axes[0].get_title()
    assert _has_class_key(first) and _has_class_key(last)
    with pytest.raises(ValueError, match="iteration: expected"):
        plot_classification(paper_fit, "4", iteration="middle")


def test_fig10_11_convergence(sim, paper_fit):
    r = paper_fit.results["4"]
    fig = plot_convergence(r, truth={"d0": 2472.0, "sigma_mp": 6.9})
    ax1, ax2 = fig.axes
    np.testing.assert_allclose(ax1.lines[0].get_ydata(), r.history["d0"])
    assert ax2.get_yscale() == "log"
    fig.canvas.draw()
    labels = [t.get_text() for t in ax2.get_yticklabels(minor=False) + ax2.get_yticklabels(
        minor=True) if t.get_text()]
    # plain numbers (7, 10, 200), never mathtext like 7x10^0
    assert len(labels) >= 2 and all(float(t) > 0 for t in labels), labels
    # a short log axis (less than a decade) still has labelled ticks
    short = plot_convergence(bm.fit(sim.survey, rng=0).results["4"])
    short.canvas.draw()
    ax = short.axes[1]
    assert len([t for t in ax.get_yticklabels(minor=True) + ax.get_yticklabels()
                if t.get_text()]) >= 2


def test_fig12_pol_sensitivity(sim):
    full = bm.simulate_survey("abe58", rng=0)
    sens = pol_sensitivity(full.survey.for_beacon("4"), [0.05, 0.1, 0.2], sigma_dp=3.97)
    assert np.all(np.diff(sens["sigma_mp"]) < 0)
    assert len(sens["flags"]) == 3
    fig = plot_pol_sensitivity(sens, truth=sim.truth["4"])
    assert len(fig.axes) == 3 and len(fig.axes[2].lines) >= 3
    assert _has_class_key(fig)


def test_fig13_and_table_ii(sim, paper_fit):
    fig = plot_survey_classification(paper_fit)
    assert len(fig.axes) == 4 and _has_class_key(fig)
    md = table_ii_markdown(paper_fit, truth=sim.truth)
    assert "| d0 (m) |" in md and "beacon depth (m)" in md and "| 2472.0 |" in md
    assert len(plot_table_ii(paper_fit).axes[0].tables) == 1


@pytest.fixture(scope="module")
def posterior(sim):
    """Beacons 2 and 4 sampled once for the figure tests (each beacon's figures are drawn
    by the same code; two keep the survey-level figures and the folder round trip honest)."""
    pings = sim.survey.table.drop(columns="true_class")
    beacons = sim.survey.beacons.reset_index()
    pings, beacons = pings[pings.beacon.isin(["2", "4"])], beacons[beacons.beacon.isin(["2", "4"])]
    return bm.sample(pings, beacons, rng=0, progress=False, n_draws=400)


def test_bayesian_figures(sim, posterior):
    post = posterior
    r = post.results["4"]
    assert len(bayes_plots.plot_trace(r).axes) == 2 * 6
    pair = bayes_plots.plot_pair(r)
    assert len(pair.axes) == 36
    assert not _overlapping_tick_labels(pair), _overlapping_tick_labels(pair)
    assert len(bayes_plots.plot_intervals(post, truth=sim.truth).axes) == 2
    classes = bayes_plots.plot_class_uncertainty(post, "4")
    assert len(classes.axes) == 2 and _has_class_key(classes)


def _overlapping_tick_labels(fig):
    """Pairs of tick labels whose boxes overlap, over the whole figure."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for ax in fig.axes if ax.axison
             for t in ax.get_xticklabels() + ax.get_yticklabels()
             if t.get_visible() and t.get_text()]
    return [(a, b) for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1:]
            if ba.overlaps(bb)]


def test_running_mean_keeps_its_level_at_both_ends():
    """The running mean of classes_vs_time averages over the values that exist at the ends:
    a constant probability stays constant (a zero-padded mean dipped to half at both ends)."""
    np.testing.assert_allclose(running_mean(np.full(500, 0.8), 101), 0.8)
    p = np.linspace(0.0, 1.0, 301)
    run = running_mean(p, 51)
    np.testing.assert_allclose(run[150], p[150])  # a straight line is kept in the middle
    assert run[0] == pytest.approx(np.mean(p[:26])) and run[-1] == pytest.approx(
        np.mean(p[-26:]))


def test_fit_output_round_trip_and_plot_command(sim, tmp_path):
    from bayes_mpem.cli import main

    res = bm.fit(sim.survey, rng=0)
    res.write(tmp_path)
    back = load_output(tmp_path)
    for b, r in res.results.items():
        assert back.results[b].d0 == r.d0
        np.testing.assert_allclose(back.results[b].resp, r.resp, atol=1e-12)
        np.testing.assert_allclose(back.results[b].history["d0"], r.history["d0"])
        np.testing.assert_allclose(back.results[b].first_resp, r.first_resp, atol=5e-4)
    assert main(["plot", str(tmp_path), "--out", str(tmp_path / "figs"), "--beacon", "3"]) == 0
    names = {p.name for p in (tmp_path / "figs").iterdir()}
    assert {"fig01_ranges.png", "fig05_track.png", "fig07_first_iteration_3.png",
            "fig08_colormap.png", "fig09_last_iteration_3.png", "fig10_11_convergence_3.png",
            "fig12_pol_sensitivity_3.png", "fig13_classification.png", "table2.png"} <= names


def test_sample_output_round_trip_and_plot(posterior, tmp_path):
    post = posterior
    post.write(tmp_path)
    back = load_output(tmp_path)
    assert set(back.results) == {"2", "4"}
    assert back.results["2"].summary["d0"] == post.results["2"].summary["d0"]
    paths = write_figures(back, tmp_path / "figs")
    assert {p.name for p in paths} == {"intervals.png", "trace_2.png", "pair_2.png",
                                       "classes_2.png", "trace_4.png", "pair_4.png",
                                       "classes_4.png"}


def test_plot_command_errors(tmp_path, capsys):
    from bayes_mpem.cli import main

    assert main(["plot", str(tmp_path)]) == 2
    assert "summary.json: not found" in capsys.readouterr().err
    (tmp_path / "summary.json").write_text(json.dumps({"beacons": {}}))
    assert main(["plot", str(tmp_path)]) == 2
    assert "no 'beacons_table'" in capsys.readouterr().err


def test_write_figures_dispatches_on_the_result_type(tmp_path):
    import pandas as pd

    from bayes_mpem.survey_in.result import SurveyInResult

    located = SurveyInResult({"transponders": {}}, pd.DataFrame({"line": [1]}))
    assert write_figures(located, tmp_path) == []
    with pytest.raises(TypeError, match="got dict"):
        write_figures({}, tmp_path)


def test_results_and_library_never_import_plots_or_report():
    import subprocess
    import sys

    code = ("import sys, bayes_mpem.lbl.survey.comparison, bayes_mpem.lbl.diagnosis.result, "
            "bayes_mpem.survey_in.survey; "
            "print(sorted(m for m in sys.modules if m.startswith(('bayes_mpem.plots', "
            "'bayes_mpem.report', 'bayes_mpem.cli'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_plot_reads_every_output_folder_kind():
    """fit, sample, compare, diagnose, locate, navigate folders (each redrawn in its own test):
    each result type of the command table reads a folder back and has figures."""
    from bayes_mpem.commands import load, with_results

    kinds = with_results()
    assert set(kinds) == {"fit", "sample", "locate", "compare", "diagnose", "navigate"}
    for command in kinds.values():
        assert callable(load(command.result).read) and callable(load(command.figures))
