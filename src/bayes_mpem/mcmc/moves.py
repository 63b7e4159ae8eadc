"""The move policy of both samplers, and a snooker update with the correct Metropolis factor.

Both posteriors are sampled with differential evolution alone
(:func:`default_moves`): among the exact move sets it gave the most effective
samples per second on the LBL beacon posterior (``benchmarks/bench_moves.py``,
``docs/benchmarks.md``), and it is what the location posterior always used.

emcee 3.1.6's ``DESnookerMove`` (the latest release) has two errors, fixed
upstream after the release: it scales the direction ``x - z`` by
``1 / sqrt(|x - z|)`` instead of ``1 / |x - z|`` (so the projections of the
helper walkers are not projections), and it multiplies the Jacobian term
``log(|x' - z| / |x - z|)`` by ``(ndim - 1) / 2`` instead of ``ndim - 1``. The
two errors together (the scaled direction also breaks the move's reversibility) leave
the chain's stationary distribution too narrow: a 5-D
standard normal sampled with DE 0.8 + that snooker 0.2 has sd 0.96 (16-D: 0.90).
:class:`SnookerMove` is ter Braak & Vrugt's (2008) snooker update as published:
a unit direction, and the factor ``(ndim - 1) log(|x' - z| / |x - z|)`` that
makes the move reversible; it is exact but, a Python loop over walkers, slower
per effective sample than DE alone here, so it is offered, not the default.
``tests/test_mcmc.py`` samples 5-D and 16-D standard normals with DE alone and
with DE 0.8 + :class:`SnookerMove` 0.2 and checks the sds against 1 within their
Monte-Carlo error; the same check fails on the 3.1.6 snooker.

References
----------
ter Braak, C. J. F. and Vrugt, J. A. (2008). Differential Evolution Markov
Chain with snooker updater and fewer chains. Statistics and Computing 18,
435-446.

Examples
--------
>>> [(type(m).__name__, w) for m, w in default_moves()]
[('DEMove', 1.0)]
"""

from __future__ import annotations

import emcee
import numpy as np

#: How :func:`default_moves` is reported in a result's diagnostics.
DEFAULT_MOVES_LABEL = "default (DEMove 1.0: differential evolution)"


class SnookerMove(emcee.moves.DESnookerMove):
    """Differential-evolution snooker update (ter Braak & Vrugt 2008), reversible.

    For walker ``x``, three other walkers ``z, z1, z2`` are drawn from the
    complementary sets; with ``e = (x - z) / |x - z|`` the proposal is
    ``x' = x + gamma e ((z1 - z2) . e)`` and the log acceptance factor
    ``(ndim - 1) log(|x' - z| / |x - z|)``.

    Parameters
    ----------
    gammas : float, default 1.7
        The step factor (ter Braak & Vrugt's recommendation).
    **kwargs
        Passed to :class:`emcee.moves.RedBlueMove` (four splits, as emcee's).
    """

    def get_proposal(self, s, c, random):
        """Propose a new position for every walker of ``s`` (emcee's move interface).

        Parameters
        ----------
        s : numpy.ndarray
            ``(n, ndim)`` positions of the walkers being moved.
        c : list of numpy.ndarray
            The complementary sets of walkers.
        random : numpy.random.RandomState
            emcee's random state.

        Returns
        -------
        q : numpy.ndarray
            ``(n, ndim)`` proposals.
        factors : numpy.ndarray
            ``(n,)`` log Metropolis-Hastings factors.
        """
        ns, ndim = s.shape
        nc = [len(x) for x in c]
        q = np.empty_like(s)
        log_ratio = np.empty(ns, dtype=np.float64)
        for i in range(ns):
            w = np.array([c[j][random.randint(nc[j])] for j in range(3)])
            random.shuffle(w)
            z, z1, z2 = w
            delta = s[i] - z
            norm = np.linalg.norm(delta)
            u = delta / norm
            q[i] = s[i] + u * self.gammas * (np.dot(u, z1) - np.dot(u, z2))
            log_ratio[i] = np.log(np.linalg.norm(q[i] - z)) - np.log(norm)
        return q, (ndim - 1.0) * log_ratio


def default_moves() -> list:
    """Differential evolution alone: the moves of both posteriors.

    Measured on beacon 4 of abe58 (``benchmarks/bench_moves.py``, 3 seeds,
    interleaved, on a loaded machine): 667 ESS/s against 566 for DE 0.8 +
    :class:`SnookerMove` 0.2, with the same posterior widths (an earlier run of the
    same script: 868 against 600);
    emcee 3.1.6's own snooker in that mix gave intervals about 9 % too narrow
    (sd of d0 0.367 m against 0.399-0.404 m).
    On SeaGap's 23-parameter location posterior the released snooker mix gave a
    depth sd of 0.055 m where DE alone, the stretch move and the Laplace
    approximation give 0.066-0.067 m.

    Returns
    -------
    list
        ``[(DEMove, 1.0)]``, emcee's ``moves`` argument.
    """
    return [(emcee.moves.DEMove(), 1.0)]
