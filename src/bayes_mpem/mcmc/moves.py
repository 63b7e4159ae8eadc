"""The emcee moves of every posterior: an independence proposal, or differential evolution."""

from __future__ import annotations

import emcee
import numpy as np

#: How :func:`default_moves` is reported in a result's diagnostics.
DEFAULT_MOVES_LABEL = "DEMove 1.0 (differential evolution)"
#: How :func:`independence_move` is reported.
INDEPENDENCE_LABEL = "MHMove 1.0 (independence proposal: Laplace Student-t)"


#: proposals drawn and evaluated per call of the target: a block of steps of all walkers
BLOCK_POINTS = 256


class IndependenceMove(emcee.moves.MHMove):
    """emcee's ``MHMove`` with an independence proposal, evaluated a block of steps at a time.

    :meth:`plan` says how many steps the next ``run_mcmc`` takes; unplanned steps propose
    one at a time. Why it is the same Markov chain: ``docs/bayes.md`` (Which move).

    Parameters
    ----------
    proposal : TProposal
        ``draw(n, random)`` and ``log_density(points)``
        (:func:`~bayes_mpem.mcmc.proposal.laplace_proposal`).
    block_points : int, default :data:`BLOCK_POINTS`
        Proposals (walkers x steps) per call of the target.

    References
    ----------
    Tierney, L. (1994). Markov chains for exploring posterior distributions. Annals of
    Statistics 22(4), 1701-1728 (section 2.3.3: independence chains).
    """

    def __init__(self, proposal, *, block_points: int | None = None):
        def propose(coords, random):
            new = proposal.draw(coords.shape[0], random)
            return new, proposal.log_density(coords) - proposal.log_density(new)

        super().__init__(propose)
        self.proposal = proposal
        self.block_points = int(block_points or BLOCK_POINTS)
        self._left = 0
        self._queue = None

    def plan(self, steps: int) -> None:
        """Draw and evaluate the proposals of the next ``steps`` steps in blocks.

        Parameters
        ----------
        steps : int
        """
        self._left, self._queue = int(steps), None

    def propose(self, model, state):
        """Take one step: the next planned proposal of every walker, accepted by emcee's rule.

        Parameters
        ----------
        model : emcee.model.Model
        state : emcee.State

        Returns
        -------
        state : emcee.State
            The walkers after the step.
        accepted : numpy.ndarray
            ``(walkers,)`` booleans.
        """
        n = state.coords.shape[0]
        if self._left <= 0:
            return super().propose(model, state)
        if self._queue is None or self._pos == self._queue[0].shape[0]:
            k = min(self._left, max(1, self.block_points // n))
            q = self.proposal.draw(k * n, model.random)
            lp = np.asarray(model.log_prob_fn(q), dtype=float)  # vectorised, no blobs: one call
            if lp.shape != (k * n,):  # not so: emcee's own evaluation
                lp, _ = model.compute_log_prob_fn(q)
            self._queue = (q.reshape(k, n, -1), np.reshape(lp, (k, n)),
                           self.proposal.log_density(q).reshape(k, n))
            self._pos = 0
        q, lp, lq = (a[self._pos] for a in self._queue)
        self._pos += 1
        self._left -= 1
        lnpdiff = lp - state.log_prob + self.proposal.log_density(state.coords) - lq
        accepted = np.log(model.random.rand(n)) < lnpdiff
        return self.update(state, emcee.State(q, log_prob=lp), accepted), accepted


def independence_move(proposal) -> list:
    """Independence Metropolis-Hastings from ``proposal`` as emcee's moves.

    Parameters
    ----------
    proposal : TProposal
        ``draw(n, random)`` and ``log_density(points)``
        (:func:`~bayes_mpem.mcmc.proposal.laplace_proposal`).

    Returns
    -------
    list
        ``[(IndependenceMove, 1.0)]``.
    """
    return [(IndependenceMove(proposal), 1.0)]


def default_moves() -> list:
    """Differential evolution alone: the ensemble's moves where no proposal fits.

    Returns
    -------
    list
        ``[(DEMove, 1.0)]``, emcee's ``moves`` argument.

    References
    ----------
    ter Braak, C. J. F. and Vrugt, J. A. (2008). Differential Evolution Markov Chain with
    snooker updater and fewer chains. Statistics and Computing 18, 435-446.

    Examples
    --------
    >>> [(type(m).__name__, w) for m, w in default_moves()]
    [('DEMove', 1.0)]
    """
    return [(emcee.moves.DEMove(), 1.0)]
