"""The emcee moves of both posteriors: an independence proposal, or differential evolution.

Imported on first use (emcee's import costs 0.5 s).

References
----------
Tierney, L. (1994). Markov chains for exploring posterior distributions. Annals of
Statistics 22(4), 1701-1728 (section 2.3.3: independence chains).
ter Braak, C. J. F. and Vrugt, J. A. (2008). Differential Evolution Markov Chain with
snooker updater and fewer chains. Statistics and Computing 18, 435-446.

Examples
--------
>>> [(type(m).__name__, w) for m, w in default_moves()]
[('DEMove', 1.0)]
"""

from __future__ import annotations

import emcee

#: How :func:`default_moves` is reported in a result's diagnostics.
DEFAULT_MOVES_LABEL = "DEMove 1.0 (differential evolution)"
#: How :func:`independence_move` is reported.
INDEPENDENCE_LABEL = "MHMove 1.0 (independence proposal: Laplace Student-t)"


def independence_move(proposal) -> list:
    """Independence Metropolis-Hastings from ``proposal`` as emcee's moves.

    Each walker proposes a fresh draw of ``proposal`` whatever its position, so
    each walker is its own Markov chain: ESS and R-hat over walkers as chains are
    exact.

    Parameters
    ----------
    proposal : TProposal
        ``draw(n, random)`` and ``log_density(points)``
        (:func:`~bayes_mpem.mcmc.proposal.laplace_proposal`).

    Returns
    -------
    list
        ``[(emcee.moves.MHMove, 1.0)]``; its log ratio is ``log q(x) - log q(x')``.
    """

    def propose(coords, random):
        new = proposal.draw(coords.shape[0], random)
        return new, proposal.log_density(coords) - proposal.log_density(new)

    return [(emcee.moves.MHMove(propose), 1.0)]


def default_moves() -> list:
    """Differential evolution alone: the ensemble's moves where no proposal fits.

    Returns
    -------
    list
        ``[(DEMove, 1.0)]``, emcee's ``moves`` argument.
    """
    return [(emcee.moves.DEMove(), 1.0)]
