"""The report of an array: sound speed with its band, residuals per transponder, the array map
in cm against the priors, and the files write_figures writes for an array folder."""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from scipy.stats import chi2

from bayes_mpem.exceptions import InputError
from bayes_mpem.plots.survey_in import (
    plot_array_map,
    plot_gradients,
    plot_residuals_by_transponder,
    plot_sound_speed,
)
from bayes_mpem.report import load_output, write_figures
from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa, true_speed_change
from bayes_mpem.survey_in.travel_times import speed_basis

GRADIENT_TRUTH = {"shallow_east": "grad1_east", "shallow_north": "grad1_north",
                  "deep_east": "grad2_east", "deep_north": "grad2_north"}


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


def test_a_classified_table_cut_short_is_refused(array, tmp_path):
    """Figures are not drawn from a truncated file."""
    array.write(tmp_path)
    path = tmp_path / "classified.csv"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:len(lines) // 2]) + lines[len(lines) // 2][:7])
    with pytest.raises(InputError, match=r"classified.csv: \d+ rows; expected \d+, the \d+ "
                       r"pings and 0 skipped lines of .*summary.json: the file is cut short"):
        load_output(tmp_path)


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


@pytest.fixture(scope="module")
def gradient_campaign():
    """An acceptance campaign of issue 26 (6 h, gradients in the water), located by default."""
    sim = simulate_gnssa(hours=6.0, rng=2, speed_model="field", track="star+circle",
                         gradients=True)
    return sim, locate_array_survey(sim.raw())


def test_the_gradients_series_follows_their_averages_and_says_where_it_is_about(
        gradient_campaign):
    sim, res = gradient_campaign
    g = res.summary["gradients"]
    ser = g["series"]
    assert ser["time_s"] == res.summary["sound_speed"]["series"]["time_s"]
    for name in GRADIENT_TRUTH:
        m, sd = np.asarray(ser[name]["mean"]), np.asarray(ser[name]["sd"])
        assert m.size == sd.size == len(ser["time_s"]) and np.all(sd > 0)
        # the time average over the shots against the average over the series' even times
        assert abs(m.mean() - g[name]["mean"]) < 0.2 * g[name]["sd"], name
    fit = res.fits["array"]
    # each term's curve and sd from its own block of the coefficients and covariance
    t = np.asarray(ser["time_s"])
    B = speed_basis(pd.DataFrame({"time": t}), fit.model["speed_intervals"],
                    fit.model["time_range"], fit.model.get("speed_breaks"))
    K, k = len(fit.ids), B.shape[1]
    for j, name in enumerate(GRADIENT_TRUTH):
        block = slice(3 * K + k + j * k, 3 * K + k + (j + 1) * k)
        coef = fit.gradient_coef[j * k:(j + 1) * k]
        sd = np.sqrt(np.einsum("ij,jk,ik->i", B, fit.cov[block, block], B))
        assert ser[name]["mean"] == pytest.approx(B @ coef * fit.sound_speed, rel=1e-12)
        assert ser[name]["sd"] == pytest.approx(sd * fit.sound_speed, rel=1e-9)
    shots = array_shots(sim.raw()).iloc[fit.rows]
    p = [np.mean(0.5 * (shots[f"{c}_tx"] + shots[f"{c}_rx"])) for c in "en"]
    assert g["origins_m"]["shallow"] == pytest.approx(p)
    assert g["origins_m"]["deep"] == pytest.approx(fit.start[:, :2].mean(axis=0))


def test_the_series_bands_cover_the_truth(gradient_campaign):
    """The 95 % bands hold the true series at most times (the study: benchmarks/gnssa_smooth.py).
    The speed is the speed about the gradient terms' origins; about the array centre its band
    misses the truth on this campaign."""
    sim, res = gradient_campaign
    truth = sim.truth_record()
    ss = res.summary["sound_speed"]
    t = np.asarray(ss["series"]["time_s"])
    origins = res.summary["gradients"]["origins_m"]

    def covered(mean, sd, true):
        return np.mean(np.abs(np.asarray(mean) - true) < 1.96 * np.asarray(sd))

    true_v = ss["reference_m_s"] + true_speed_change(truth, t, origins)
    assert covered(ss["series"]["mean_m_s"], ss["series"]["sd_m_s"], true_v) > 0.9
    about_centre = ss["reference_m_s"] + true_speed_change(truth, t)
    assert covered(ss["series"]["mean_m_s"], ss["series"]["sd_m_s"], about_centre) < 0.8
    tg = truth["gradients"]
    for name, key in GRADIENT_TRUTH.items():
        s = res.summary["gradients"]["series"][name]
        assert covered(s["mean"], s["sd"], np.interp(t, tg["time_s"], tg[key])) > 0.9, name
    # the figure draws the truth about the same points
    fig = plot_sound_speed(res, truth=truth)
    line = next(ln for ln in fig.axes[0].lines if ln.get_label().startswith("truth"))
    tt = np.asarray(truth["sound_speed"]["series"]["time_s"])
    assert line.get_ydata() == pytest.approx(
        ss["reference_m_s"] + true_speed_change(truth, tt, origins), rel=0, abs=1e-9)
    plt.close(fig)


def test_true_speed_change_about_other_points():
    truth = {"sound_speed": {"series": {"time_s": [0.0, 10.0], "dV0_m_s": [0.0, 1.0]}},
             "array_centre": {"east": 100.0, "north": -50.0, "up": -1500.0},
             "gradients": {"time_s": [0.0, 10.0], "grad1_east": [0.1, 0.1],
                           "grad1_north": [0.0, 0.2], "grad2_east": [0.05, 0.05],
                           "grad2_north": [0.0, 0.0]}}
    assert true_speed_change(truth, [5.0]) == pytest.approx([0.5])
    at_centre = {"shallow": [100.0, -50.0], "deep": [100.0, -50.0]}
    assert true_speed_change(truth, [5.0], at_centre) == pytest.approx([0.5])
    # 1 km east and north of the centre for the shallow term, 2 km west for the deep one
    away = {"shallow": [1100.0, 950.0], "deep": [-1900.0, -50.0]}
    assert true_speed_change(truth, [5.0], away) == pytest.approx([0.5 + 0.1 + 0.1 - 0.1])
    assert true_speed_change({**truth, "gradients": None}, [5.0], away) == pytest.approx([0.5])


def test_the_gradients_figure(gradient_campaign, array, tmp_path):
    sim, res = gradient_campaign
    fig = plot_gradients(res, truth=sim.truth_record())
    assert len(fig.axes) == 2  # shallow, deep
    for ax, term in zip(fig.axes, ("shallow", "deep"), strict=True):
        assert ax.get_title().startswith(term)
        assert len(ax.collections) == 2  # an east and a north band
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert labels[0].startswith("east") and "truth" in labels[1]
        east = res.summary["gradients"]["series"][f"{term}_east"]["mean"]
        assert ax.lines[0].get_ydata() == pytest.approx(east)
    plt.close(fig)
    assert "gradients.png" in {p.name for p in write_figures(res, tmp_path)}
    with pytest.raises(ValueError, match="gradients: not fitted"):
        plot_gradients(array)
    assert array.summary["gradients"]["series"] is None
    assert "gradients.png" not in {p.name for p in write_figures(array, tmp_path / "none")}
    plt.close("all")
