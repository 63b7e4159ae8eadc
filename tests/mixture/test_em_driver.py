"""The EM driver: monotone likelihood, the ConvergenceWarning, the final E-step, resuming."""

import numpy as np
import pytest
from scipy.special import logsumexp

from bayes_mpem.exceptions import ConvergenceWarning, LocateWarning
from bayes_mpem.mixture.em import EMModel, EMRun, best_run, run_em


class GaussianMixture(EMModel):
    """A 1-D Gaussian mixture, every parameter free: ``(weights, means, variances)``."""

    def __init__(self, x):
        self.x = x

    def e_step(self, params):
        w, mu, var = params
        logp = np.log(w) - 0.5 * ((self.x[:, None] - mu) ** 2 / var + np.log(2 * np.pi * var))
        lse = logsumexp(logp, axis=1)
        return float(lse.sum()), np.exp(logp - lse[:, None])

    def m_step(self, params, resp):
        n = resp.sum(axis=0)
        mu = resp.T @ self.x / n
        var = np.einsum("nk,nk->k", resp, (self.x[:, None] - mu) ** 2) / n
        return n / n.sum(), mu, np.maximum(var, 1e-6)


def _data(seed, n=300):
    gen = np.random.default_rng(seed)
    return np.r_[gen.normal(0.0, 1.0, n), gen.normal(3.0, 0.5, n // 2), gen.normal(8, 2, n // 3)]


START = (np.full(3, 1 / 3), np.array([-1.0, 1.0, 2.0]), np.ones(3))


@pytest.mark.parametrize("seed", range(4))
def test_monotonic_likelihood(seed):
    """scikit-learn's test_monotonic_likelihood: one iteration at a time, never a loss."""
    model = GaussianMixture(_data(seed))
    run = run_em(model, START, tol=1e-12, max_iter=1)
    for _ in range(60):
        nxt = run_em(model, tol=1e-12, max_iter=run.n_iter + 1, resume=run)
        assert nxt.loglik >= run.loglik - 1e-9 * abs(run.loglik)
        run = nxt
    ll = np.asarray(run.history["loglik"])
    assert ll.size == 62 and np.all(np.diff(ll) >= -1e-9 * np.abs(ll[1:]))
    assert ll[-1] > ll[0] + 10.0  # it did move


def test_convergence_warning_when_max_iter_is_hit():
    model = GaussianMixture(_data(0))
    with pytest.warns(ConvergenceWarning, match="not converged after 3 iterations"):
        run = run_em(model, START, tol=1e-12, max_iter=3,
                     warn=lambda r: f"not converged after {r.n_iter} iterations")
    assert not run.converged and run.n_iter == 3 and len(run.history["loglik"]) == 4
    with pytest.warns(LocateWarning):
        run_em(model, START, tol=1e-12, max_iter=3, warn=lambda r: "no", category=LocateWarning)
    quiet = run_em(model, START, tol=1e-12, max_iter=3)  # no warn=: no warning (errors here)
    assert not quiet.converged


def test_converges_and_stops_on_the_tolerance():
    model = GaussianMixture(_data(1))
    run = run_em(model, START, tol=1e-6, max_iter=1000)
    ll = run.history["loglik"]
    assert run.converged and run.n_iter < 1000
    assert abs(ll[-1] - ll[-2]) < 1e-6 <= abs(ll[-2] - ll[-3])


@pytest.mark.parametrize("max_iter", [1, 5, 1000])
def test_final_e_step_matches_the_returned_parameters(max_iter):
    model = GaussianMixture(_data(2))
    run = run_em(model, START, tol=1e-8, max_iter=max_iter)
    loglik, resp = model.e_step(run.params)
    assert run.loglik == loglik
    np.testing.assert_array_equal(run.resp, resp)
    np.testing.assert_array_equal(run.first_resp, model.e_step(START)[1])


def test_without_final_e_step_the_probabilities_are_those_of_the_last_m_step():
    class Lagged(GaussianMixture):
        final_e_step = False

    model = Lagged(_data(3))
    run = run_em(model, START, tol=1e-12, max_iter=4)
    before = run_em(model, START, tol=1e-12, max_iter=3)
    np.testing.assert_array_equal(run.resp, model.e_step(before.params)[1])
    assert not np.array_equal(run.resp, model.e_step(run.params)[1])


def test_resume_continues_the_same_run():
    model = GaussianMixture(_data(4))
    straight = run_em(model, START, tol=1e-8, max_iter=12)
    part = run_em(model, START, tol=1e-8, max_iter=5)
    resumed = run_em(model, tol=1e-8, max_iter=12, resume=part)
    assert resumed.n_iter == straight.n_iter == 12
    assert resumed.history == straight.history
    for a, b in zip(resumed.params, straight.params, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(resumed.first_resp, straight.first_resp)


def test_unusable_parameters_stop_the_loop():
    class Collapsing(GaussianMixture):
        calls = 0

        def m_step(self, params, resp):
            w, mu, var = super().m_step(params, resp)
            self.calls += 1
            return w, mu, var * 0.0 if self.calls == 3 else var  # the scales collapse at 3

        def usable(self, params):
            return bool(np.all(params[2] > 0))

    model = Collapsing(_data(5))
    with pytest.warns(ConvergenceWarning, match="collapsed"):
        run = run_em(model, START, tol=1e-12, max_iter=50, warn=lambda r: "collapsed")
    assert not run.converged and run.n_iter == 3 and np.all(run.params[2] == 0.0)
    assert len(run.history["loglik"]) == 3  # the start and 2 iterations: no E-step at the 3rd
    before = run_em(GaussianMixture(model.x), START, tol=1e-12, max_iter=2)
    np.testing.assert_array_equal(run.resp, before.resp)


def test_best_run_keeps_the_highest_likelihood_and_the_first_of_equals():
    def run(ll, tag):
        return EMRun(params=tag, resp=None, loglik=ll, n_iter=1, converged=True, history={},
                     first_resp=None)

    assert best_run([run(-3.0, "a"), run(-1.0, "b"), run(-1.0, "c"), run(-2.0, "d")]).params == "b"
    assert best_run([]) is None


def test_the_package_mixture_em_never_loses_likelihood():
    """The per-beacon mixture EM through the driver: its recorded log-likelihood is monotone."""
    from bayes_mpem.lbl.em.em_mixture import fit_mixture_em
    from bayes_mpem.lbl.simulation.simulate import simulate_survey

    sim = simulate_survey("abe58", rng=4, n_cycles=400)
    res = fit_mixture_em(sim.survey.for_beacon("2"), n_init=1, tol=1e-12, max_iter=40, rng=0)
    ll = res.history["loglik"]
    assert np.all(np.diff(ll) >= -1e-9 * np.abs(ll[1:]))
