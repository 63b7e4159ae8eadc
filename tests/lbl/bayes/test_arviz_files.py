"""The posterior files open in ArviZ as its users expect (docs/bayes.md, "Opening the posterior
in ArviZ").

``sample`` writes one file per beacon, ``posterior_<id>.nc``, its ArviZ groups at the root.
The current generation (``xarray.open_datatree``, ``arviz_base.from_netcdf``, arviz-stats) and
the legacy one (``arviz.from_netcdf``, ``arviz<1`` in the ``test`` extra) open it as it is.
arviz-plots (the ``arviz-plots`` extra) draws from it where installed.
"""

import json

import numpy as np
import pytest
import xarray as xr

import bayes_mpem as bm

GROUPS = ["posterior", "sample_stats", "observed_data", "log_likelihood"]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    sim = bm.simulate_survey("abe58", rng=4, n_cycles=300)
    post = bm.sample(sim.survey, rng=1, progress=False, min_ess=300, log_likelihood=True)
    out = tmp_path_factory.mktemp("post")
    return post, out, post.write(out)


def test_one_file_per_beacon_and_no_other(written):
    post, out, paths = written
    summary = json.loads((out / "summary.json").read_text())
    assert sorted(p.name for p in out.glob("*.nc")) == sorted(
        f"posterior_{b}.nc" for b in post.results)
    for bid, r in post.results.items():
        assert summary["beacons"][bid]["file"] == f"posterior_{bid}.nc"
        tree = xr.open_datatree(paths[f"posterior_{bid}"])  # no engine, no group
        assert "arviz.from_netcdf" in tree.attrs["contents"] and tree.attrs["beacon"] == bid
        assert sorted(tree.children) == sorted(GROUPS)
        np.testing.assert_array_equal(tree["posterior"]["d0"], r.idata.posterior["d0"])
        obs = tree["observed_data"]
        assert obs["z"].attrs["units"] == "m" and obs["time"].attrs["units"] == "s"
        np.testing.assert_array_equal(obs["range"], r.rows)
        assert tree["log_likelihood"]["z"].dtype == np.float32
        # the ping times stay float64 (as float32, epoch times were a minute off)
        np.testing.assert_array_equal(tree["log_likelihood"]["time"], obs["time"])
        assert tree["log_likelihood"]["time"].dtype == np.float64


def test_file_names_stay_plain_whatever_the_id():
    from bayes_mpem.lbl.survey.sampling import posterior_file

    assert posterior_file("4") == "posterior_4.nc"
    assert posterior_file("../etc/x y") == "posterior_.._etc_x_y.nc"


def test_summary_ess_is_what_arviz_computes_from_the_file(written):
    import arviz_stats as azs

    _, out, paths = written
    summary = json.loads((out / "summary.json").read_text())
    for bid, b in summary["beacons"].items():
        tree = xr.open_datatree(out / b["file"])
        ess, rhat = azs.ess(tree, method="bulk"), azs.rhat(tree)
        for k, v in b["ess"].items():
            assert float(ess[k]) == pytest.approx(v, rel=1e-12), (bid, k)
            assert float(rhat[k]) == pytest.approx(b["rhat"][k], rel=1e-12), (bid, k)


def test_current_arviz_reads_the_file(written):
    import arviz_base as azb
    import arviz_stats as azs

    post, _, paths = written
    tree = azb.convert_to_datatree(str(paths["posterior_4"]))  # a path is opened
    loo = azs.loo(tree)
    assert loo.n_data_points == post.results["4"].idata.observed_data.sizes["range"]


def test_legacy_arviz_reads_the_file(written):
    az = pytest.importorskip("arviz", reason="legacy ArviZ (arviz<1) is in the test extra")
    if int(az.__version__.split(".")[0]) >= 1:
        pytest.skip("arviz >= 1 is the DataTree generation")
    import arviz_stats as azs

    _, _, paths = written
    idata = az.from_netcdf(paths["posterior_4"])
    assert sorted(idata.groups()) == sorted(GROUPS)
    elpd_legacy = az.loo(idata).elpd_loo
    elpd_current = azs.loo(xr.open_datatree(paths["posterior_4"])).elpd
    assert elpd_legacy == pytest.approx(elpd_current, rel=1e-5)
    summary = az.summary(idata, var_names=["d0", "sigma_mp"], round_to="none")
    assert summary.loc["d0", "mean"] == pytest.approx(
        float(idata.posterior["d0"].mean()), rel=1e-9)


def test_default_file_is_small_and_compressed(written, tmp_path):
    post, _, paths = written
    lean = bm.sample(post.survey, rng=1, progress=False, min_ess=300)
    small = lean.write(tmp_path / "lean")["posterior_4"]
    plain = lean.write(tmp_path / "plain", compress=False)["posterior_4"]
    assert "log_likelihood" not in xr.open_datatree(small).children
    assert small.stat().st_size < 0.2 * paths["posterior_4"].stat().st_size
    import h5py

    with h5py.File(small) as f, h5py.File(plain) as g:
        assert f["posterior/d0"].compression == "gzip"
        assert g["posterior/d0"].compression is None
    with h5py.File(paths["posterior_4"]) as f:
        assert f["log_likelihood/z"].compression == "gzip"


def test_arviz_plots_draws_from_the_file(written, tmp_path):
    azp = pytest.importorskip("arviz_plots", reason="the arviz-plots extra is not installed")

    _, _, paths = written
    tree = xr.open_datatree(paths["posterior_4"])
    for name in ("plot_trace_dist", "plot_dist", "plot_forest", "plot_pair", "plot_rank",
                 "plot_ess"):
        pc = getattr(azp, name)(tree, var_names=["d0", "sigma_mp"], backend="matplotlib")
        pc.savefig(tmp_path / f"{name}.png")
        assert (tmp_path / f"{name}.png").stat().st_size > 5_000, name


def _summary_rhat(tree, x):
    """docs/bayes.md, "Diagnostics from the file": summary.json's R-hat of a (chain, draw)
    array of the file, the recipe as printed there."""
    import arviz_stats as azs

    ens = tree["posterior"]["ensemble"].values  # each walker's (chain's) ensemble
    if tree.attrs["n_ensembles"] == 1:  # the walkers are the chains
        return float(azs.rhat(x))
    # each ensemble's walkers pooled step by step into one chain
    return float(azs.rhat(np.stack([x[ens == e].T.ravel() for e in np.unique(ens)])))


@pytest.fixture(scope="module")
def ensembles(tmp_path_factory):
    sim = bm.simulate_survey("abe58", rng=4, n_cycles=120)
    post = bm.sample(sim.survey, rng=2, progress=False, min_ess=300, sampler="ensemble",
                     n_ensembles=3)
    out = tmp_path_factory.mktemp("ensembles")
    post.write(out)
    return post, out


def test_the_summary_diagnostics_of_several_ensembles_come_back_from_the_file(ensembles):
    """The summary's R-hat compares the ensembles, each one's walkers pooled; the file did not
    say which walker was whose, and ArviZ on it gave R-hat 1.01-1.03 where the summary said
    about 1.001 (session 47). Each chain's ensemble is now the coordinate ``ensemble``, and
    the recipe of docs/bayes.md gives the summary's R-hat (the ESS: ArviZ's as it is)."""
    import arviz_stats as azs

    post, out = ensembles
    summary = json.loads((out / "summary.json").read_text())
    for bid, b in summary["beacons"].items():
        assert b["diagnostics"]["n_ensembles"] == 3 and b["diagnostics"]["sampler"] == "ensemble"
        tree = xr.open_datatree(out / b["file"])
        assert tree.attrs["n_ensembles"] == 3 and "pooled" in tree.attrs["diagnostics"]
        walkers = b["diagnostics"]["n_walkers"]
        for group in ("posterior", "sample_stats"):
            np.testing.assert_array_equal(tree[group]["ensemble"],
                                          np.repeat(np.arange(3), walkers))
        ess = azs.ess(tree, method="bulk")
        for k, v in b["rhat"].items():
            assert _summary_rhat(tree, tree["posterior"][k].values) == pytest.approx(
                v, abs=1e-6), (bid, k)
            assert float(ess[k]) == pytest.approx(b["ess"][k], rel=1e-9), (bid, k)


def test_legacy_arviz_gives_the_summary_rhat_of_ensembles_too(ensembles):
    az = pytest.importorskip("arviz", reason="legacy ArviZ (arviz<1) is in the test extra")
    if int(az.__version__.split(".")[0]) >= 1:
        pytest.skip("arviz >= 1 is the DataTree generation")

    _, out = ensembles
    summary = json.loads((out / "summary.json").read_text())
    b = summary["beacons"]["4"]
    post = az.from_netcdf(out / b["file"]).posterior
    ens = post["ensemble"].values
    for k, v in b["rhat"].items():
        x = post[k].values
        pooled = np.stack([x[ens == e].T.ravel() for e in np.unique(ens)])
        assert float(az.rhat(pooled)) == pytest.approx(v, abs=1e-6), k
        assert abs(float(az.rhat(x)) - v) > 1e-6  # walkers as chains: not the summary's


def test_one_ensemble_files_say_so(written):
    _, out, paths = written
    tree = xr.open_datatree(paths["posterior_4"])
    assert tree.attrs["n_ensembles"] == 1
    assert (tree["posterior"]["ensemble"] == 0).all()
    summary = json.loads((out / "summary.json").read_text())
    for k, v in summary["beacons"]["4"]["rhat"].items():
        assert _summary_rhat(tree, tree["posterior"][k].values) == pytest.approx(v, abs=1e-9)
