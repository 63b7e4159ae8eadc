"""``bayes-mpem locate --sample`` on a GNSS-A array: end to end on a small simulated campaign."""

import json

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.cli import main


@pytest.fixture(scope="module")
def located(tmp_path_factory):
    """A 0.5 h GNATSS campaign, located and sampled by the command line."""
    d = tmp_path_factory.mktemp("array_sample")
    assert main(["simulate", "--gnssa", "--format", "gnatss", "--out", str(d / "sim"),
                 "--seed", "2", "--hours", "0.5", "--no-gradients"]) == 0
    assert main(["locate", str(d / "sim" / "config.yaml"), "--out", str(d / "out"),
                 "--sample", "--seed", "3", "--min-ess", "400", "--no-progress"]) == 0
    return d


def test_array_sample_end_to_end(located, capsys):
    out = located / "out"
    summary = json.loads((out / "summary.json").read_text())
    assert "posterior_array.nc" in summary["files"]
    assert summary["interval_method"] == "posterior"
    truth = json.loads((located / "sim" / "truth.json").read_text())
    centre = summary["array_centre"]["enu"]
    for a in ("east", "north", "up"):
        lo, hi = centre[a]["interval"]
        assert lo < centre[a]["mean"] < hi
        # within 4 posterior sds of the truth (a 1-in-15,000 miss for a calibrated posterior)
        assert abs(centre[a]["mean"] - truth["array_centre"][a]) < 4 * centre[a]["sd"]
    cls = pd.read_csv(out / "classified.csv")
    used = cls["label"].isin(["true", "spurious"])
    assert cls.loc[used, "p_true_sd"].notna().all() and (cls.loc[used, "p_true_sd"] >= 0).all()
    assert "posterior" in (out / "solution.txt").read_text()


def test_posterior_file_opens_and_summary_ess_is_arviz_on_the_file(located):
    import arviz_base as azb
    import arviz_stats as azs
    import xarray as xr

    out = located / "out"
    summary = json.loads((out / "summary.json").read_text())
    tree = xr.open_datatree(out / "posterior_array.nc")
    assert {"posterior", "sample_stats", "observed_data", "class_probabilities"} <= set(
        tree.children)
    tree = azb.convert_to_datatree(str(out / "posterior_array.nc"))
    ess, rhat = azs.ess(tree, method="bulk"), azs.rhat(tree)
    for tid, t in summary["transponders"].items():
        for a in ("east", "north", "up"):
            sel = {"transponder": tid, "axis": a}
            assert float(ess["position"].sel(sel)) == pytest.approx(t["posterior"]["ess"][a],
                                                                    rel=1e-12)
            assert float(rhat["position"].sel(sel)) == pytest.approx(
                t["posterior"]["rhat"][a], rel=1e-12)
    for a in ("east", "north", "up"):
        assert float(ess["centre"].sel(axis=a)) == pytest.approx(
            summary["array_centre"]["ess"][a], rel=1e-12)
        assert float(tree["posterior"]["centre"].sel(axis=a).std(ddof=1)) == pytest.approx(
            summary["array_centre"]["enu"][a]["sd"], rel=1e-9)
    obs = tree["observed_data"]
    assert obs["twtt"].attrs["units"] == "s" and np.all(np.diff(obs["time"].values) >= -1e9)


def test_same_seed_same_summary(located, tmp_path):
    assert main(["locate", str(located / "sim" / "config.yaml"), "--out", str(tmp_path / "b"),
                 "--sample", "--seed", "3", "--min-ess", "400", "--no-progress"]) == 0
    a = (located / "out" / "summary.json").read_text()
    assert a == (tmp_path / "b" / "summary.json").read_text()


def test_sample_options_without_sample_are_refused_for_arrays(located, capsys):
    assert main(["locate", str(located / "sim" / "config.yaml"), "--out",
                 str(located / "c"), "--seed", "3"]) == 2
    assert "--seed" in capsys.readouterr().err


def test_array_sample_with_every_coordinate_held(tmp_path, capsys):
    """Every sigma 0 (positions and centre held): nothing to sample for the positions; the
    run finishes and says so (it ended with "min() arg is an empty sequence", exit 2)."""
    from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa

    sim = simulate_gnssa(hours=0.5, rng=2)  # held where they are: at the prior, not 3 m off
    sim.header["transponders"] = sim.truth["transponders"].copy()
    site = sim.write(tmp_path / "sim")["survey"]
    lines = []
    for ln in site.read_text().splitlines():
        key = ln.split("=")[0].strip()
        if key.endswith("_dPos") or key == "dCentPos":
            parts = ln.split("=")[1].split()
            ln = f" {key} = " + " ".join(parts[:3] + ["0.0"] * 3 + parts[6:])
        lines.append(ln)
    site.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert main(["locate", str(site), "--out", str(tmp_path / "out"), "--sample", "--seed", "1",
                 "--min-ess", "100", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert out.count("coordinates held, not sampled") == 4
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert all(t["posterior"]["ess"] == {} for t in summary["transponders"].values())
