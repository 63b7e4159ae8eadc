"""The report of an array: sound speed with its band, residuals per transponder, the array map
in cm against the priors, and the files write_figures writes for an array folder."""

import matplotlib.pyplot as plt
import numpy as np
import pytest
from scipy.stats import chi2

from bayes_mpem.plots.survey_in import (
    plot_array_map,
    plot_residuals_by_transponder,
    plot_sound_speed,
)
from bayes_mpem.report import load_output, write_figures
from bayes_mpem.survey_in.array_survey import locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa


@pytest.fixture(scope="module")
def array():
    return locate_array_survey(simulate_gnssa(n_transponders=3, hours=0.5, rng=1,
                                              speed_model="field").raw(), speed_intervals=3)


def test_sound_speed_band_follows_the_series(array):
    fig, ax = plt.subplots()
    assert plot_sound_speed(array, ax=ax) is fig
    ser = array.summary["sound_speed"]["series"]
    band = ax.collections[0].get_paths()[0].vertices[:, 1]
    sd = np.asarray(ser["sd_m_s"])
    width = np.ptp(band)
    assert width >= 2 * 1.959 * sd.min() and np.ptp(ser["mean_m_s"]) <= width
    assert ax.lines[0].get_ydata() == pytest.approx(ser["mean_m_s"])
    plt.close(fig)


def test_residuals_one_panel_per_transponder(array):
    fig = plot_residuals_by_transponder(array)
    assert len(fig.axes) == 3
    for ax in fig.axes:
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert labels[0].startswith("true") and labels[1].startswith("spurious")
    plt.close(fig)


def test_array_map_ellipses_in_cm_about_the_prior(array):
    fig = plot_array_map(array)
    assert len(fig.axes) == 1 + 1 + 3  # the map, the centre, each transponder
    t = array.summary["transponders"]["M01"]
    ax = next(a for a in fig.axes if a.get_title().startswith("M01"))
    ell = ax.patches[0]
    cov_cm = 1e4 * np.asarray(t["covariance"]["matrix"])[:2, :2]
    major = 2 * np.sqrt(chi2.ppf(0.95, 2) * np.linalg.eigvalsh(cov_cm).max())
    assert max(ell.width, ell.height) == pytest.approx(major, rel=1e-6)
    d = [100 * (t["enu"][c]["mean"] - t["prior"][c]) for c in ("east", "north")]
    assert ell.center == pytest.approx(d)
    plt.close(fig)


def test_write_figures_for_an_array_folder(array, tmp_path):
    array.write(tmp_path)
    paths = write_figures(load_output(tmp_path), tmp_path)
    names = {p.name for p in map(type(tmp_path), paths)}
    assert {"array_map.png", "sound_speed.png", "residuals_by_transponder.png",
            "survey_map.png"} <= names
    assert all((tmp_path / n).stat().st_size > 10_000 for n in names)
    assert (tmp_path / "solution.txt").is_file()
    plt.close("all")


def test_truth_is_marked_where_given(tmp_path):
    sim = simulate_gnssa(n_transponders=3, hours=0.5, rng=1, speed_model="field")
    res = locate_array_survey(sim.raw(), speed_intervals=3)
    truth = sim.truth_record()
    fig = plot_array_map(res, truth=truth)
    ax = next(a for a in fig.axes if a.get_title().startswith("M02"))
    t, pr = truth["transponders"]["M02"], truth["prior"]["M02"]
    marker = next(ln for ln in ax.lines if ln.get_label().startswith("truth"))
    assert marker.get_xydata()[0] == pytest.approx([100 * (t[c] - pr[c])
                                                    for c in ("east", "north")])
    fig2 = plot_sound_speed(res, truth=truth)
    line = next(ln for ln in fig2.axes[0].lines if ln.get_label().startswith("truth"))
    fitted = np.interp(np.asarray(truth["sound_speed"]["series"]["time_s"]) / 3600.0,
                       fig2.axes[0].lines[0].get_xdata(), fig2.axes[0].lines[0].get_ydata())
    assert np.abs(line.get_ydata() - fitted).max() < 0.1  # m/s: the fit follows the truth
    names = {p.name for p in write_figures(res, tmp_path, truth=truth)}
    assert "array_map.png" in names
    plt.close("all")
