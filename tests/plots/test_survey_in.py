"""Survey-in figures: drawn from a located survey and from its folder, every class keyed."""

from pathlib import Path

import matplotlib.pyplot as plt
import pytest

from bayes_mpem.cli import main
from bayes_mpem.io.formats import read_survey
from bayes_mpem.plots.style import SURVEY_IN_COLORS
from bayes_mpem.plots.survey_in import plot_residual_histogram, plot_residuals, plot_survey_map
from bayes_mpem.report import load_output, write_figures
from bayes_mpem.survey_in.array_survey import locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa
from bayes_mpem.survey_in.survey import locate_survey

DATA = Path(__file__).resolve().parents[2] / "data" / "obsrange"


@pytest.fixture(scope="module")
def cc03():
    return locate_survey(read_survey(DATA / "SIO_CC03.txt"))


@pytest.fixture(scope="module")
def array():
    return locate_array_survey(simulate_gnssa(n_transponders=3, hours=0.5, rng=1).raw(),
                               speed_intervals=2)


def _keyed(ax):
    """The axes' legend names both classes, in their colours."""
    leg = ax.get_legend()
    labels = [t.get_text() for t in leg.get_texts()] if leg else []
    return any(s.startswith("true") for s in labels) and any(s.startswith("spurious")
                                                            for s in labels)


@pytest.mark.parametrize("which", ["cc03", "array"])
def test_residual_figures_have_a_class_key(which, request):
    res = request.getfixturevalue(which)
    fig = plot_residuals(res)
    assert _keyed(fig.axes[0])
    colours = {tuple(c.get_facecolor()[0][:3]) for c in fig.axes[0].collections
               if len(c.get_offsets())}
    assert len(colours) == 2  # one colour per class, from plots.style
    fig2 = plot_residual_histogram(res)
    assert _keyed(fig2.axes[0])
    plt.close("all")
    assert SURVEY_IN_COLORS["true"] != SURVEY_IN_COLORS["spurious"]


def test_map_shows_drop_point_track_and_ellipse(cc03):
    fig = plot_survey_map(cc03)
    main_ax, close = fig.axes[0], fig.axes[1]
    labels = [t.get_text() for t in main_ax.get_legend().get_texts()]
    assert labels == ["ship's track", "solution", "drop point"]
    assert len(close.patches) == 1  # the ellipse
    width = close.patches[0].width
    assert 1.0 < width < 4.0  # CC03's 95 % ellipse: about 2 m across
    plt.close(fig)


def test_array_map_has_one_closeup_per_transponder(array):
    fig = plot_survey_map(array)
    assert len(fig.axes) == 1 + 3
    plt.close(fig)


def test_locate_figures_and_plot_on_the_folder(tmp_path):
    assert main(["locate", str(DATA / "SIO_CC03.txt"), "--out", str(tmp_path), "--figures"]) == 0
    names = ("survey_map.png", "residuals.png", "residual_histogram.png")
    sizes = {n: (tmp_path / n).stat().st_size for n in names}
    assert min(sizes.values()) > 10_000
    for n in names:
        (tmp_path / n).unlink()
    assert main(["plot", str(tmp_path)]) == 0
    assert all((tmp_path / n).stat().st_size > 10_000 for n in names)
    back = load_output(tmp_path)
    assert list(back.summary["transponders"]) == ["CC03"] and len(back.classified) == 121
    assert [p.name for p in write_figures(back, tmp_path / "again")] == list(names)
