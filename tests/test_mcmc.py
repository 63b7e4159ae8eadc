"""The shared emcee driver: the protocol, the loop and the chain summaries."""

import re

import emcee
import numpy as np
import pytest
from released_snooker import ReleasedSnooker

import bayes_mpem as bm
from bayes_mpem import mcmc
from bayes_mpem.exceptions import SamplingWarning
from bayes_mpem.lbl.bayes.posterior import BeaconPosterior
from bayes_mpem.lbl.em.em_mixture import fit_mixture_em
from bayes_mpem.mcmc.moves import default_moves


class Gauss:
    """A correlated 2-D Gaussian satisfying the protocol."""

    names, ndim, label = ("a", "b"), 2, "test gaussian"
    prec = np.linalg.inv(np.array([[1.0, 0.8], [0.8, 1.0]]))

    def start(self, n_walkers, gen):
        return 0.1 * gen.standard_normal((n_walkers, 2))

    def __call__(self, theta):
        return -0.5 * np.einsum("wi,ij,wj->w", theta, self.prec, theta)


@pytest.fixture(scope="module")
def beacon4():
    return bm.simulate_survey("abe58", rng=0, n_cycles=700).survey.for_beacon("4")


def test_both_posteriors_satisfy_the_protocol(beacon4):
    post = BeaconPosterior(beacon4, em=fit_mixture_em(beacon4, rng=0))
    assert isinstance(post, mcmc.LogPosterior)
    assert post.label == "beacon 4 (learned priors)"
    start = post.start(24, np.random.default_rng(0))
    assert start.shape == (24, post.ndim) and np.all(np.isfinite(post(start)))
    assert isinstance(Gauss(), mcmc.LogPosterior)


def test_start_needs_the_em_solution(beacon4):
    with pytest.raises(ValueError, match="start needs the EM solution"):
        BeaconPosterior(beacon4).start(24, np.random.default_rng(0))


def _run(seed, **kw):
    gen = np.random.default_rng(seed)
    opts = {"moves": mcmc.default_moves(), "gen": gen, "min_ess": 400, "burn_in": True,
            "progress": False, "label": "test gaussian", **kw}
    return mcmc.run_ensembles(Gauss(), [Gauss().start(16, gen)], **opts), gen


def test_same_seed_same_chain_and_order_of_draws():
    (a, ga), (b, gb), (c, _) = _run(1), _run(1), _run(2)
    np.testing.assert_array_equal(a.chain, b.chain)
    assert ga.random() == gb.random()  # the generator advanced the same way
    assert not np.array_equal(a.chain[-1], c.chain[-1])
    assert a.converged and a.chain.shape[1:] == (16, 2)
    assert a.log_prob.shape == a.chain.shape[:2]


def test_stops_on_arviz_ess_and_rhat():
    """The run stops once ArviZ's bulk ESS of the kept chain reaches the target and R-hat is
    below 1.01, both recomputed here from the chain with arviz_stats."""
    from arviz_stats.base import array_stats

    r, _ = _run(3, min_ess=600)
    for i in range(2):
        x = r.chain[:, :, i].T
        assert array_stats.ess(x, method="bulk") >= 600
        assert array_stats.rhat(x) < 1.01
    assert min(array_stats.ess(r.chain[:, :, i].T, method="bulk") for i in range(2)) == r.ess


def test_independence_move_is_exact_and_needs_no_burn_in():
    """emcee's MHMove with a deliberately offset and widened t proposal still samples the
    target: each walker is its own chain, the mean and sd within Monte-Carlo error."""
    target = Gauss()
    prop = mcmc.TProposal(centre=np.array([0.5, -0.5]), chol=1.5 * np.eye(2), df=5.0)
    gen = np.random.default_rng(0)
    r = mcmc.run_ensembles(target, [prop.draw(32, gen)], moves=mcmc.independence_move(prop),
                           gen=gen, min_ess=4000, progress=False)
    assert r.burn == 0 and r.converged
    x = r.chain.reshape(-1, 2)
    se = 1.0 / np.sqrt(r.ess)
    np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=4 * se)
    np.testing.assert_allclose(x.std(axis=0), 1.0, atol=4 * se)
    assert np.corrcoef(x.T)[0, 1] == pytest.approx(0.8, abs=0.05)


def test_laplace_proposal_finds_the_mode():
    target = lambda u: -0.5 * ((u - 1.0) ** 2 / np.array([1.0, 4.0])).sum(axis=1)  # noqa: E731
    q = mcmc.laplace_proposal(target, [0.0, 0.0], [1.0, 1.0])
    np.testing.assert_allclose(q.centre, 1.0, atol=1e-6)
    np.testing.assert_allclose(q.chol @ q.chol.T, np.diag([1.0, 4.0]), atol=1e-6)
    assert mcmc.laplace_proposal(lambda u: 0.5 * (u ** 2).sum(axis=1), [0.0], [1.0]) is None


def test_step_cap_warns_with_the_label():
    with pytest.warns(SamplingWarning, match=r"test gaussian: the chain reached max_steps=50"):
        r, _ = _run(0, max_steps=50, min_ess=10_000, warn=True)
    assert not r.converged and r.n_steps == 50


def test_progress_lines_when_not_a_terminal(capsys, monkeypatch):
    """progress="auto" writes plain lines when standard error is not a terminal, as under
    pytest: the steps, the ESS and R-hat against their targets, with thousands separators."""
    from bayes_mpem.mcmc import progress

    monkeypatch.setattr(progress, "LOG_INTERVAL", 0.0)
    r, _ = _run(0, min_ess=1200, progress="auto")
    lines = capsys.readouterr().err.splitlines()
    assert r.converged and len(lines) >= 2
    assert re.fullmatch(r"\[sampler\] test gaussian: step \d+ of ~[\d,]+: ESS [\d,]+, target "
                        r"1,200; R-hat \d\.\d{3}, target < 1\.01; \d+\.\d s", lines[0]), lines[0]
    assert re.fullmatch(rf"\[sampler\] test gaussian: done, {r.n_steps:,} steps x 16 walkers: "
                        r"ESS [\d,]+, target 1,200; R-hat \d\.\d{3}, target < 1\.01; "
                        r"\d+\.\d s", lines[-1]), lines[-1]
    with pytest.warns(SamplingWarning):
        _run(0, max_steps=50, min_ess=10_000, progress="log")
    assert "stopped at max_steps=50, 50 steps" in capsys.readouterr().err


def test_progress_bar_total_and_modes(capsys):
    assert mcmc.progress_mode("auto") == "log"  # pytest captures stderr: not a terminal
    assert mcmc.progress_mode(True) == "bar" and mcmc.progress_mode(None) is None
    with pytest.raises(ValueError, match="progress: expected"):
        mcmc.progress_mode("verbose")
    rep = mcmc.SamplingProgress("bar", "x", min_ess=1000, max_rhat=1.01, max_steps=20000,
                                n_walkers=32)
    rep.update(63, 1307.2, 1.004, expected=95.2)
    assert (rep.bar.n, rep.bar.total) == (63, 96)
    rep.finish(steps=63, converged=True, ess=1307.0, rhat=1.004)
    assert "ESS 1,307, target 1,000; R-hat 1.004" in capsys.readouterr().err and rep.bar is None


def test_move_policies():
    assert [(type(m).__name__, w) for m, w in mcmc.default_moves()] == [("DEMove", 1.0)]
    prop = mcmc.TProposal(centre=np.zeros(2), chol=np.eye(2), df=10.0)
    [(move, w)] = mcmc.independence_move(prop)
    assert isinstance(move, emcee.moves.MHMove) and w == 1.0
    x = np.array([[0.0, 0.0], [3.0, 1.0]])
    new, log_ratio = move.get_proposal(x, np.random.RandomState(0))
    np.testing.assert_allclose(log_ratio, prop.log_density(x) - prop.log_density(new))


@pytest.mark.parametrize(("kept", "n_chains", "n_draws"), [(1000, 50, 400), (7, 4, 1000),
                                                          (500, 24, 1)])
def test_thin_index_ends_at_the_last_step(kept, n_chains, n_draws):
    idx, thin = mcmc.thin_index(kept, n_chains, n_draws)
    assert idx[-1] == kept - 1 and idx[0] >= 0
    assert np.all(np.diff(idx) == thin)
    least = max(1, min(kept, int(np.ceil(n_draws / n_chains))))
    assert least <= len(idx) < 2 * least + 1


def test_draw_moments_match_a_direct_computation():
    rng = np.random.default_rng(3)
    flat = rng.uniform(size=(150, 2))
    x = np.linspace(0, 1, 7)

    def fn(theta):
        p = 1 / (1 + np.exp(-(theta[:, [0]] * x - theta[:, [1]])))
        return np.log(p), [p, 1 - p]

    ll, m, s = mcmc.draw_moments(flat, fn, chunk=32)
    p = 1 / (1 + np.exp(-(flat[:, [0]] * x - flat[:, [1]])))
    np.testing.assert_allclose(ll, np.log(p), rtol=1e-14)
    np.testing.assert_allclose(m, np.column_stack([p.mean(0), 1 - p.mean(0)]), rtol=1e-12)
    np.testing.assert_allclose(s[:, 0], p.std(0), rtol=1e-9)
    assert mcmc.draw_moments(flat, lambda t: (None, fn(t)[1]))[0] is None


def test_intervals_and_ess_are_arviz_stats():
    from arviz_stats.base import array_stats

    rng = np.random.default_rng(0)
    x = rng.normal(size=20000)
    lo, hi = mcmc.hdi(x, 0.9)
    assert [lo, hi] == pytest.approx(list(array_stats.hdi(x, 0.9)), rel=1e-12)
    assert np.mean((x >= lo) & (x <= hi)) == pytest.approx(0.9, abs=2e-3)
    assert mcmc.equal_tailed(x, 0.9) == pytest.approx(list(np.quantile(x, [0.05, 0.95])))
    series = rng.normal(size=(8, 2000))  # (chain, draw), independent draws
    assert mcmc.bulk_ess({"x": series})["x"] == pytest.approx(16000, rel=0.1)
    assert mcmc.rhat(series) == pytest.approx(1.0, abs=0.01)
    # two ensembles of 4 walkers: R-hat compares the ensembles, each pooled into one chain
    shifted = series + np.repeat([0.0, 1.0], 4)[:, None]
    ess, rhat = mcmc.ess_and_rhat({"x": shifted}, n_ens=2)
    pooled = shifted.reshape(2, 4, 2000).transpose(0, 2, 1).reshape(2, -1)
    assert ess == {"x": mcmc.ess(shifted)} and rhat == {"x": mcmc.rhat(pooled)}
    assert rhat["x"] > 1.1 and mcmc.ess_and_rhat({"x": series})[1]["x"] < 1.01


# ----------------------------------------------------------------------- exact moves


def _sd_z(moves, ndim, seed, n_steps=6000, n_walkers=32):
    """(sd - 1) / its Monte-Carlo error, pooled over the coordinates of a standard normal.

    The error of a sample sd is about ``1 / sqrt(2 ESS)``; ESS from emcee's
    integrated autocorrelation time of the squared coordinates (what sd depends on).
    The walkers of an ensemble are not independent chains, nor are the coordinates
    independent under DE moves, so this z overstates the precision: over 40 seeds its sd
    was 1.1-1.9 instead of 1 (an independent review's measurement), hence the bands below.
    """
    sampler = emcee.EnsembleSampler(n_walkers, ndim, lambda th: -0.5 * np.sum(th * th, axis=1),
                                    vectorize=True, moves=moves)
    sampler.random_state = np.random.RandomState(seed).get_state()
    start = np.random.default_rng(seed).standard_normal((n_walkers, ndim))
    sampler.run_mcmc(start, n_steps, progress=False)
    chain = sampler.get_chain(discard=n_steps // 5)  # (steps, walkers, ndim)
    tau = emcee.autocorr.integrated_time(chain ** 2, tol=0, quiet=True)
    ess = chain.shape[0] * chain.shape[1] / tau  # per coordinate
    sd = np.sqrt(np.mean(chain ** 2, axis=(0, 1)))
    se = 1.0 / np.sqrt(2.0 * ess)
    # pooled over coordinates (independent): the mean of the z-scores times sqrt(ndim)
    return float(np.mean((sd - 1.0) / se) * np.sqrt(ndim)), sd


@pytest.mark.slow
@pytest.mark.parametrize("ndim", [5])
def test_shipped_moves_sample_a_standard_normal_exactly(ndim):
    """Differential evolution keeps N(0, I): |z| < 8, i.e. about 4 standard deviations of z
    itself (sd up to ~1.9); the released snooker sits at z -11 to -42."""
    z, sd = _sd_z(mcmc.default_moves(), ndim, seed=ndim)
    assert abs(z) < 8.0, sd


@pytest.mark.slow
@pytest.mark.parametrize("ndim", [5])
def test_the_check_catches_emcee_3_1_6_snooker(ndim):
    """The released snooker in the same mix is too narrow (sd 0.96 at 5-D, 0.91 at 16-D)."""
    z, sd = _sd_z([(emcee.moves.DEMove(), 0.8), (ReleasedSnooker(), 0.2)], ndim, seed=ndim)
    assert z < -8.0, sd


def test_to_datatree_is_arviz_from_dict():
    import arviz_base as azb
    import xarray as xr

    gen = np.random.default_rng(0)
    groups = {"posterior": {"d0": gen.random((4, 5))}, "observed_data": {"z": gen.random(3)}}
    kw = {"dims": {"z": ["range"]}, "coords": {"range": np.arange(3) * 2}}
    ref, ours = azb.from_dict(groups, **kw), mcmc.to_datatree(groups, attrs={"a": 1}, **kw)
    for g in ref.children:
        xr.testing.assert_identical(ref[g].dataset.drop_attrs(), ours[g].dataset.drop_attrs())
    assert ours.attrs["a"] == 1


def test_a_ctrl_c_inside_the_target_is_raised_after_the_block_without_emcee_s_dump(capsys):
    """emcee prints the parameters and a traceback for an exception in its target; the
    driver holds a Ctrl-C to the end of the block and raises it there."""
    calls = {"n": 0, "after": 0}

    def target(x):
        calls["n"] += 1
        if calls["n"] == 5:
            raise KeyboardInterrupt
        if calls["n"] > 5:
            calls["after"] += 1
        return -0.5 * (x ** 2).sum(axis=1)

    gen = np.random.default_rng(0)
    with pytest.raises(KeyboardInterrupt):
        mcmc.run_ensembles(target, [gen.standard_normal((16, 2))],
                           moves=default_moves(), gen=gen, min_ess=400,
                           progress=False)
    out, err = capsys.readouterr()
    assert "emcee" not in out + err and "Traceback" not in err
    assert calls["after"] == 0  # the target is not called again once interrupted
