"""The posterior files open in ArviZ as its users expect (docs/bayes.md, "Opening the posterior
in ArviZ").

``posterior_<id>.nc`` holds one beacon's groups at its root: the current generation
(``xarray.open_datatree``, ``arviz_base.convert_to_datatree``, arviz-stats) and the legacy one
(``arviz.from_netcdf``, ``arviz<1``, in the ``test`` extra: both generations install side by
side) open it with no extra argument. arviz-plots (the ``arviz-plots`` extra, which needs
``matplotlib<3.11`` and ``xarray<2026.4``) draws from it; that test runs where the extra is
installed (``.ci/run`` installs it in a second environment) and is skipped elsewhere.
"""

import numpy as np
import pytest
import xarray as xr

import bayes_mpem as bm

GROUPS = ["posterior", "log_likelihood", "sample_stats", "observed_data"]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    sim = bm.simulate_survey("abe58", rng=4, n_cycles=300)
    post = bm.sample(sim.survey, rng=1, progress=False, min_ess=300)
    out = tmp_path_factory.mktemp("post")
    return post, out, post.write(out)


def test_one_file_per_beacon_with_the_groups_at_its_root(written):
    post, out, paths = written
    assert sorted(p.name for p in out.glob("posterior*.nc")) == [
        "posterior.nc", *(f"posterior_{b}.nc" for b in sorted(post.results))]
    combined = xr.open_datatree(paths["posterior"])
    assert "xarray.open_datatree" in combined.attrs["contents"]
    for bid, r in post.results.items():
        tree = xr.open_datatree(paths[f"posterior_{bid}"])  # no engine, no group
        assert list(tree.children) == GROUPS
        assert tree.attrs["beacon"] == bid
        for group in GROUPS:
            xr.testing.assert_identical(tree[group].to_dataset(),
                                        combined[f"beacon_{bid}/{group}"].to_dataset())
        np.testing.assert_array_equal(tree["posterior"]["d0"], r.idata.posterior["d0"])


def test_current_arviz_reads_the_file(written):
    import arviz_base as azb
    import arviz_stats as azs

    post, _, paths = written
    tree = azb.convert_to_datatree(str(paths["posterior_4"]))
    assert list(tree.children) == GROUPS
    loo = azs.loo(tree)
    assert loo.n_data_points == post.results["4"].idata.observed_data.sizes["range"]


def test_legacy_arviz_reads_the_file(written):
    az = pytest.importorskip("arviz", reason="legacy ArviZ (arviz<1) is in the test extra")
    if int(az.__version__.split(".")[0]) >= 1:
        pytest.skip("arviz >= 1 is the DataTree generation")
    import arviz_base as azb
    import arviz_stats as azs

    _, _, paths = written
    idata = az.from_netcdf(paths["posterior_4"])  # no extra argument
    assert list(idata.groups()) == GROUPS
    assert idata.posterior.sizes == xr.open_datatree(paths["posterior_4"]).posterior.sizes
    elpd_legacy = az.loo(idata).elpd_loo
    elpd_current = azs.loo(azb.convert_to_datatree(str(paths["posterior_4"]))).elpd
    assert elpd_legacy == pytest.approx(elpd_current, rel=1e-5)
    summary = az.summary(idata, var_names=["d0", "sigma_mp"], round_to="none")
    assert summary.loc["d0", "mean"] == pytest.approx(
        float(idata.posterior["d0"].mean()), rel=1e-9)
    # the combined file has no group at its root: legacy ArviZ sees nothing there, which the
    # root attribute "contents" and the docs explain
    assert list(az.from_netcdf(paths["posterior"]).groups()) == []


def test_arviz_plots_draws_from_the_file(written, tmp_path):
    azp = pytest.importorskip("arviz_plots", reason="the arviz-plots extra is not installed")
    import arviz_base as azb

    _, _, paths = written
    tree = azb.convert_to_datatree(str(paths["posterior_4"]))
    for name in ("plot_trace_dist", "plot_dist", "plot_forest", "plot_pair", "plot_rank",
                 "plot_ess"):
        pc = getattr(azp, name)(tree, var_names=["d0", "sigma_mp"], backend="matplotlib")
        pc.savefig(tmp_path / f"{name}.png")
        assert (tmp_path / f"{name}.png").stat().st_size > 5_000, name
