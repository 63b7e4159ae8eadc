"""The independence move's blocks of proposals and the driver's emcee sampler."""

import emcee
import numpy as np

from bayes_mpem import mcmc
from bayes_mpem.mcmc.driver import _sampler_class
from bayes_mpem.mcmc.moves import IndependenceMove


class Counted:
    """A standard normal that counts the points and calls it evaluates."""

    def __init__(self):
        self.points = self.calls = 0

    def __call__(self, x):
        self.points += len(x)
        self.calls += 1
        return -0.5 * np.sum(x * x, axis=1)


def test_planned_blocks_evaluate_each_proposal_once_in_few_calls():
    """125 planned steps of 16 walkers: 2,000 proposals in ceil(125 / 16) = 8 calls, none
    wasted; an unplanned step proposes alone (emcee's MHMove)."""
    prop = mcmc.TProposal(centre=np.zeros(3), chol=np.eye(3), df=10.0)
    target = Counted()
    move = IndependenceMove(prop, block_points=256)
    sampler = emcee.EnsembleSampler(16, 3, target, vectorize=True, moves=[(move, 1.0)])
    state = emcee.State(prop.draw(16, np.random.default_rng(0)), log_prob=np.zeros(16))
    move.plan(125)
    state = sampler.run_mcmc(state, 125, skip_initial_state_check=True)
    assert (target.points, target.calls) == (2000, 8)
    sampler.run_mcmc(state, 3, skip_initial_state_check=True)  # unplanned
    assert (target.points, target.calls) == (2048, 11)
    assert sampler.get_chain().shape == (128, 16, 3)


def test_block_proposals_sample_the_target_exactly():
    """A planned independence chain from an offset, widened proposal: each walker's own
    chain has the target's mean and sd within Monte-Carlo error, over three seeds."""
    prop = mcmc.TProposal(centre=np.array([0.7]), chol=np.array([[1.6]]), df=4.0)
    for seed in range(3):
        gen = np.random.default_rng(seed)
        r = mcmc.run_ensembles(Counted(), [prop.draw(16, gen)],
                               moves=[(IndependenceMove(prop, block_points=100), 1.0)],
                               gen=gen, min_ess=3000, progress=False)
        x = r.chain.ravel()
        se = 1.0 / np.sqrt(r.ess)
        assert abs(x.mean()) < 4 * se and abs(x.std() - 1.0) < 4 * se * 0.75


def test_driver_sampler_gives_emcee_s_chain_seed_for_seed():
    """Reading random_state as None skips emcee's per-step snapshot and changes no draw."""
    start = np.random.default_rng(1).standard_normal((12, 2))
    chains = []
    for cls in (emcee.EnsembleSampler, _sampler_class()):
        s = cls(12, 2, lambda x: -0.5 * np.sum(x * x, axis=1), vectorize=True,
                moves=mcmc.default_moves())
        s.random_state = np.random.RandomState(7).get_state()
        state = s.run_mcmc(start, 40)
        s.run_mcmc(state, 40)  # a second block continues the same generator
        chains.append(s.get_chain())
    np.testing.assert_array_equal(chains[0], chains[1])
