import matplotlib.pyplot as plt
import numpy as np
import pytest

from bayes_mpem.lbl.navigate import navigate, simulate_dive
from bayes_mpem.plots.navigate import (
    ellipse_axes,
    plot_nav_correction,
    plot_nav_ranges,
    plot_nav_track,
)
from bayes_mpem.report import write_figures


@pytest.fixture(scope="module")
def nav_and_sim():
    sim = simulate_dive("abe58", rng=0, n_cycles=150)
    return navigate(sim.survey, rng=0, path="triangle"), sim


def test_ellipse_axes_of_a_rotated_covariance():
    a = np.deg2rad(30.0)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    cov = R @ np.diag([9.0, 1.0]) @ R.T
    w, h, ang = ellipse_axes(cov[None], q=1.0)
    assert w[0] == pytest.approx(6.0) and h[0] == pytest.approx(2.0)
    assert ang[0] % 180 == pytest.approx(30.0)


def test_figures_draw_track_ranges_and_correction(nav_and_sim, tmp_path):
    nav, sim = nav_and_sim
    fig = plot_nav_track(nav, truth=sim.true_track)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels[:3] == ["dead reckoning", "truth", "navigated"] and "95 %" in labels[3]
    plt.close(fig)
    fig = plot_nav_ranges(nav)
    assert len(fig.axes) == 4 and sum(len(c.get_offsets()) for a in fig.axes
                                      for c in a.collections) == nav.dive.n
    plt.close(fig)
    fig = plot_nav_correction(nav, truth=sim.true_track)
    assert len(fig.axes) == 2 and len(fig.axes[0].lines) == 2
    plt.close(fig)
    paths = write_figures(nav, tmp_path, truth=sim.true_track)
    assert [p.name for p in paths] == ["nav_track.png", "nav_ranges.png", "nav_correction.png"]


def _content(fig):
    """Every axis' drawn data: lines, scatter offsets and colours, ellipse sizes."""
    out = []
    for ax in fig.axes:
        out.append([np.asarray(line.get_xydata()) for line in ax.lines])
        for c in ax.collections:
            out.append([np.asarray(c.get_offsets()), np.asarray(c.get_facecolors())]
                       + [np.asarray(getattr(c, a)) for a in ("_widths", "_heights", "_angles")
                          if hasattr(c, a)])
            if hasattr(c, "get_paths") and not hasattr(c, "_widths"):
                out.append([p.vertices for p in c.get_paths()])
        out.append([ax.get_xlabel(), ax.get_ylabel()])
    return out


def _assert_same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        if isinstance(x, list):
            _assert_same(x, y)
        elif isinstance(x, str):
            assert x == y
        else:
            np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-9)


def test_a_navigate_folder_read_back_draws_the_same_figures(nav_and_sim, tmp_path, monkeypatch):
    from bayes_mpem.lbl.navigate import ecm, normal
    from bayes_mpem.lbl.navigate.result import Navigation
    from bayes_mpem.report import load_output

    nav, _ = nav_and_sim
    nav.write(tmp_path)
    for mod, name in ((ecm, "run"), (ecm, "gauss_newton"), (normal, "solve")):
        monkeypatch.setattr(mod, name, lambda *a, **k: pytest.fail("the record ran a fit"))
    rec = load_output(tmp_path)
    assert isinstance(rec, Navigation)
    assert rec.dive.n_epochs == nav.dive.n_epochs and rec.skipped == nav.skipped
    np.testing.assert_array_equal(rec.dive.epoch, nav.dive.epoch)
    np.testing.assert_array_equal(rec.dive.beacon, nav.dive.beacon)
    for draw in (plot_nav_track, plot_nav_ranges, plot_nav_correction):
        a, b = draw(nav), draw(rec)
        _assert_same(_content(a), _content(b))
        plt.close(a)
        plt.close(b)
    paths = write_figures(rec, tmp_path / "again")
    assert [p.name for p in paths] == ["nav_track.png", "nav_ranges.png", "nav_correction.png"]
