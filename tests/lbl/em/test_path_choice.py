"""path="auto": triangle or double bounce per beacon, recorded, and a forced wrong path warns."""

import json
import warnings

import pytest

import bayes_mpem as bm
from bayes_mpem.cli import main
from bayes_mpem.exceptions import FitQualityWarning, PathChoiceWarning
from bayes_mpem.lbl.em.path_choice import CLEAR_MARGIN, PathChoice, check_path_choice, choose_path
from bayes_mpem.report import load_output

QUICK = dict(progress=False, min_ess=0, max_steps=300, n_draws=200)


@pytest.fixture(scope="module")
def double():
    return bm.simulate_survey("abe58", rng=2, path="double")


@pytest.mark.parametrize("preset, kind, seed", [("abe58", "triangle", 0), ("abe58", "double", 2),
                                                ("random", "triangle", 3),
                                                ("random", "double", 4)])
def test_auto_picks_the_true_path(preset, kind, seed):
    sim = bm.simulate_survey(preset, rng=seed, path=kind)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PathChoiceWarning)
        res = bm.fit(sim.survey, rng=0)
    assert {c.path for c in res.path_choices.values()} == {kind}
    assert all(c.margin > CLEAR_MARGIN for c in res.path_choices.values())
    assert all(r.path == kind for r in res.results.values())
    for b, r in res.results.items():
        assert abs(r.d0 - sim.truth[b]["d0"]) < 5


def test_forced_wrong_path_warns_per_beacon_and_right_one_does_not(double):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = bm.fit(double.survey, path="triangle", rng=0)
    warned = [w for w in seen if issubclass(w.category, PathChoiceWarning)]
    assert len(warned) == 4 and ("beacon 1 (the mixture EM's path choice): path='triangle' "
                                 "was forced") in str(warned[0].message)
    assert warned[0].filename == __file__  # points at the caller of fit
    assert all(c.margin < -CLEAR_MARGIN and c.path == "triangle"
               for c in res.path_choices.values())
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitQualityWarning)  # PathChoiceWarning is one too
        bm.fit(double.survey, path="double", rng=0)
        bm.fit(double.survey, rng=0)  # the losing triangle fits' warnings are dropped


def test_auto_equals_the_old_triangle_default_on_triangle_data():
    sim = bm.simulate_survey("abe58", rng=21)
    auto, forced = bm.fit(sim.survey, rng=0), bm.fit(sim.survey, path="triangle", rng=0)
    for b, r in auto.results.items():
        assert r.d0 == forced.results[b].d0 and r.sigma_mp == forced.results[b].sigma_mp
        assert r.loglik == forced.results[b].loglik


def test_the_forced_fit_and_the_callers_stream_are_those_of_a_single_fit():
    """Above 20,000 replies the EM subsamples its starts (it draws from ``rng``): the path
    asked for draws as one ``fit_mixture_em`` did, the other geometry from a child stream, so
    the caller's next draw (the next beacon, the sampler) is the same as before path choice."""
    import numpy as np

    from bayes_mpem.lbl.em.em_mixture import fit_mixture_em

    data = bm.simulate_survey("abe58", rng=3, n_cycles=22_500).survey.for_beacon("4")
    assert data.n > 20_000
    for path in ("triangle", "double"):
        gen_a, gen_b = np.random.default_rng(7), np.random.default_rng(7)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            choice = choose_path(data, path, rng=gen_a)
            alone = fit_mixture_em(data, path=path, rng=gen_b)
        assert choice.fit.d0 == alone.d0 and choice.fit.loglik == alone.loglik
        assert gen_a.random() == gen_b.random()


def test_summary_records_choice_and_reads_back(double, tmp_path):
    res = bm.fit(double.survey, rng=0)
    res.write(tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    entry = summary["beacons"]["4"]["path_choice"]
    assert entry["requested"] == "auto" and entry["path"] == "double"
    assert entry["margin"] == pytest.approx(entry["loglik"]["double"] - entry["loglik"]["triangle"])
    assert summary["options"]["path"] == "auto"
    back = load_output(tmp_path)
    assert back.summary()["beacons"]["4"]["path_choice"] == entry
    assert "double" in back.format_table()
    # an output folder written before path="auto" existed still loads
    for s in summary["beacons"].values():
        del s["path_choice"]
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    old = load_output(tmp_path)
    assert old.path_choices == {} and "path_choice" not in old.summary()["beacons"]["4"]


def test_paper_method_runs_on_the_chosen_path(double):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = bm.fit(double.survey, method="paper", sigma_dp=3.97, rng=0)
    assert {r.path for r in res.results.values()} == {"double"}
    assert res.summary()["beacons"]["4"]["path_choice"]["path"] == "double"


def test_sample_and_compare_choose_then_sample_the_chosen_path():
    sim = bm.simulate_survey("abe58", rng=5, path="double", n_cycles=150)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        post = bm.sample(sim.survey, rng=0, **QUICK)
        cmp = bm.compare(sim.survey, rng=0, **QUICK)
    assert post.results and {r.path for r in post.results.values()} == {"double"}
    b = next(iter(post.results))
    assert post.summary()["beacons"][b]["path_choice"]["path"] == "double"
    assert post.results[b].em is post.path_choices[b].fit  # the EM chosen starts the walkers
    assert cmp.results and {r.learned.path for r in cmp.results.values()} == {"double"}
    assert cmp.to_dict()["beacons"][next(iter(cmp.results))]["path_choice"]["path"] == "double"
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        bm.sample(sim.survey, path="triangle", rng=0, **QUICK)
    assert any(issubclass(w.category, PathChoiceWarning) for w in seen)


def test_choose_path_options(double):
    with pytest.raises(ValueError, match="path"):
        check_path_choice("both")
    with pytest.raises(ValueError, match="path"):
        bm.fit(double.survey, path="both")
    c = choose_path(double.survey.for_beacon("1"), "double", rng=0)
    again = PathChoice.from_dict("1", c.to_dict())
    assert again.to_dict() == c.to_dict() and again.margin == c.margin


def test_cli_fit_and_sample_default_to_auto(tmp_path, capsys):
    sim = bm.simulate_survey("abe58", rng=6, path="double", n_cycles=150)
    sim.write(tmp_path / "survey")
    files = [str(tmp_path / "survey" / "pings.csv"), "--beacons",
             str(tmp_path / "survey" / "beacons.csv")]
    assert main(["fit", *files, "--out", str(tmp_path / "fit")]) == 0
    out = capsys.readouterr().out
    assert "path" in out.splitlines()[0] and "double" in out
    summary = json.loads((tmp_path / "fit" / "summary.json").read_text())
    assert {s["path_choice"]["path"] for s in summary["beacons"].values()} == {"double"}
    with pytest.raises(SystemExit):
        main(["sample", *files, "--out", str(tmp_path / "s"), "--path", "both"])
