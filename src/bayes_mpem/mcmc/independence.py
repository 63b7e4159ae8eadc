"""Independence Metropolis-Hastings from a Laplace (Student-t) proposal.

When a posterior is close to Gaussian in unconstrained coordinates (one
beacon's five parameters from thousands of ranges are), a proposal that
ignores the current state and draws from a Student-t centred on the mode,
with the inverse Hessian as its scale, is accepted most of the time and gives
nearly independent draws. The Metropolis-Hastings acceptance
``min(1, w(u') / w(u))`` with ``w = p / q`` makes the chain exact for the
target whatever the proposal; how good the proposal is decides only the
efficiency, which the rank-normalised ESS and R-hat over several chains
measure (:mod:`.convergence`). Because the proposals do not depend on the
chain, every proposal of every chain is evaluated in one vectorised call of
the target before the accept/reject pass.

:func:`laplace_proposal` finds the mode (Newton steps on a finite-difference
Hessian, all points of a step in one call) and returns a :class:`TProposal`;
:func:`run_independence` runs the chains to a stopping rule.

References
----------
Tierney (1994), Markov chains for exploring posterior distributions, Annals
of Statistics 22(4), 1701-1728 (section 2.3.3: independence chains).
Mengersen and Tweedie (1996), Rates of convergence of the Hastings and
Metropolis algorithms, Annals of Statistics 24(1), 101-121 (uniform
ergodicity when ``p / q`` is bounded, as with heavier-tailed proposals).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .convergence import ess_bulk, rhat_rank


@dataclass(frozen=True)
class TProposal:
    """Multivariate Student-t with ``df`` degrees of freedom, location ``centre``, scale ``chol``.

    Attributes
    ----------
    centre : numpy.ndarray
        ``(ndim,)``.
    chol : numpy.ndarray
        ``(ndim, ndim)`` lower Cholesky factor of the scale matrix.
    df : float
    """

    centre: np.ndarray
    chol: np.ndarray
    df: float

    def draw(self, n: int, gen: np.random.Generator) -> np.ndarray:
        """Draw ``n`` points.

        Parameters
        ----------
        n : int
        gen : numpy.random.Generator

        Returns
        -------
        numpy.ndarray
            ``(n, ndim)``.
        """
        d = self.centre.size
        z = gen.standard_normal((n, d)) @ self.chol.T
        return self.centre + z * np.sqrt(self.df / gen.chisquare(self.df, size=n))[:, None]

    def log_density(self, u) -> np.ndarray:
        """Log density up to a constant.

        Parameters
        ----------
        u : array_like
            ``(n, ndim)`` points.

        Returns
        -------
        numpy.ndarray
            ``(n,)``.
        """
        r = np.linalg.solve(self.chol, (np.atleast_2d(u) - self.centre).T)
        return -0.5 * (self.df + self.centre.size) * np.log1p((r * r).sum(axis=0) / self.df)


def _hessian_points(u, h):
    """Return the centre, axial and diagonal points of a central-difference Hessian."""
    d = u.size
    e = np.eye(d) * h
    pts = [u]
    for i in range(d):
        pts += [u + e[i], u - e[i]]
    for i in range(d):
        for j in range(i + 1, d):
            pts += [u + e[i] + e[j], u + e[i] - e[j], u - e[i] + e[j], u - e[i] - e[j]]
    return np.array(pts)


def _derivatives(v, h):
    """Gradient and Hessian from the values at :func:`_hessian_points`."""
    d = h.size
    grad, hess = np.empty(d), np.empty((d, d))
    k = 1
    for i in range(d):
        grad[i] = (v[k] - v[k + 1]) / (2 * h[i])
        hess[i, i] = (v[k] - 2 * v[0] + v[k + 1]) / h[i] ** 2
        k += 2
    for i in range(d):
        for j in range(i + 1, d):
            hess[i, j] = hess[j, i] = (v[k] - v[k + 1] - v[k + 2] + v[k + 3]) / (4 * h[i] * h[j])
            k += 4
    return grad, hess


def laplace_proposal(target, start, step, *, df: float = 10.0, newton: int = 3):
    """Make a Student-t proposal at the mode of ``target``, scaled by the inverse Hessian there.

    Parameters
    ----------
    target : callable
        Log density of ``(n, ndim)`` points, ``(n,)`` (``-inf`` outside the support).
    start : array_like
        ``(ndim,)`` point near the mode (e.g. an EM solution).
    step : array_like
        ``(ndim,)`` rough posterior standard deviations: the first difference steps.
    df : float, default 10
        Degrees of freedom of the proposal.
    newton : int, default 3
        Newton steps (each halved until it does not lower the density); later
        difference steps are a quarter of the standard deviations found.

    Returns
    -------
    TProposal or None
        None when the Hessian is not negative definite, or a difference point
        falls outside the support (no Gaussian approximation there).

    Examples
    --------
    >>> target = lambda u: -0.5 * ((u - 1.0) ** 2 / np.array([1.0, 4.0])).sum(axis=1)
    >>> q = laplace_proposal(target, [0.0, 0.0], [1.0, 1.0])
    >>> q.centre.round(6).tolist(), (q.chol @ q.chol.T).round(6).tolist()
    ([1.0, 1.0], [[1.0, 0.0], [0.0, 4.0]])
    """
    u = np.asarray(start, dtype=float).copy()
    h = 0.25 * np.asarray(step, dtype=float)
    for it in range(newton + 1):
        v = target(_hessian_points(u, h))
        if not np.all(np.isfinite(v)):
            return None
        grad, hess = _derivatives(v, h)
        try:
            chol = np.linalg.cholesky(-hess)  # negative definite Hessian: a mode nearby
        except np.linalg.LinAlgError:
            return None
        cov = np.linalg.inv(-hess)
        h = 0.25 * np.sqrt(np.diag(cov))
        if it == newton:
            break
        du = np.linalg.solve(chol.T, np.linalg.solve(chol, grad))
        for _ in range(10):  # a step that does not lower the density
            cand = target((u + du)[None, :])[0]
            if np.isfinite(cand) and cand >= v[0] - 1e-9:
                u = u + du
                break
            du = du / 2
    return TProposal(centre=u, chol=np.linalg.cholesky(cov), df=float(df))


@dataclass(frozen=True)
class IndependenceRun:
    """Chains of independence Metropolis-Hastings.

    Attributes
    ----------
    chain : numpy.ndarray
        ``(draws, chains, ndim)``, the states (the first is each chain's first proposal).
    log_prob : numpy.ndarray
        ``(draws, chains)`` target log density of the states.
    acceptance : float
        Fraction of proposals accepted.
    ess : float
        Smallest bulk ESS over the coordinates.
    rhat : float
        Largest rank-normalised split R-hat over the coordinates.
    converged : bool
        The stopping rule was met before ``max_draws``.
    proposal : TProposal
    """

    chain: np.ndarray = field(repr=False)
    log_prob: np.ndarray = field(repr=False)
    acceptance: float
    ess: float
    rhat: float
    converged: bool
    proposal: TProposal = field(repr=False)

    @property
    def n_draws(self) -> int:
        """Draws per chain."""
        return int(self.chain.shape[0])


def _start_inside(target, proposal, gen, cur, cur_lw, cur_lp, rounds=1000):
    """Redraw, in place, the start of every chain whose first proposal fell outside the support.

    The start is then a draw of the proposal restricted to the support (an
    unchanged random stream when every first proposal is inside). Raises
    ``ValueError`` when ``rounds`` draws per chain all fall outside.
    """
    for _ in range(rounds):
        out = np.flatnonzero(~np.isfinite(cur_lp))
        if out.size == 0:
            return
        cand = proposal.draw(out.size, gen)
        lp = target(cand)
        cur[out], cur_lp[out] = cand, lp
        cur_lw[out] = lp - proposal.log_density(cand)
    raise ValueError(f"the proposal put {rounds} draws in a row outside the target's support")


def _extend(target, proposal, n, n_chains, gen, state):
    """``n`` more draws of each chain from ``state = (u, log w)`` (None: start at a proposal)."""
    prop = proposal.draw(n * n_chains, gen).reshape(n, n_chains, -1)
    flat = prop.reshape(n * n_chains, -1)
    lp = target(flat).reshape(n, n_chains)
    lw = lp - proposal.log_density(flat).reshape(n, n_chains)
    log_u = np.log(gen.uniform(size=(n, n_chains)))
    chain, chain_lp = np.empty_like(prop), np.empty_like(lp)
    if state is None:
        cur, cur_lw, cur_lp = prop[0].copy(), lw[0].copy(), lp[0].copy()
        _start_inside(target, proposal, gen, cur, cur_lw, cur_lp)
        first = 1
        chain[0], chain_lp[0] = cur, cur_lp
    else:
        cur, cur_lw, cur_lp = state
        first = 0
    accepted = 0
    for t in range(first, n):
        take = log_u[t] < lw[t] - cur_lw  # -inf (outside the support) never taken
        cur = np.where(take[:, None], prop[t], cur)
        cur_lw = np.where(take, lw[t], cur_lw)
        cur_lp = np.where(take, lp[t], cur_lp)
        accepted += int(take.sum())
        chain[t], chain_lp[t] = cur, cur_lp
    return chain, chain_lp, (cur, cur_lw, cur_lp), accepted, (n - first) * n_chains


def run_independence(target, proposal: TProposal, *, gen: np.random.Generator,
                     n_chains: int = 4, first: int = 500, min_ess: float = 1000.0,
                     max_draws: int = 20000) -> IndependenceRun:
    """Run independence chains of ``target`` from ``proposal`` until bulk ESS >= ``min_ess``.

    Parameters
    ----------
    target : callable
        Log density of ``(n, ndim)`` points (``-inf`` outside the support).
    proposal : TProposal
    gen : numpy.random.Generator
    n_chains : int, default 4
        Independent chains (R-hat compares them).
    first : int, default 500
        Draws per chain of the first block; later blocks are sized from the
        ESS per draw measured so far (with a 25 % margin).
    min_ess : float, default 1000
        Stop when the smallest bulk ESS over the coordinates reaches this and
        the largest R-hat is below 1.01.
    max_draws : int, default 20000
        Cap of draws per chain.

    Returns
    -------
    IndependenceRun
    """
    chain, lp, state, acc, tried = _extend(target, proposal, max(4, min(first, max_draws)),
                                           n_chains, gen, None)
    while True:
        cols = [chain[:, :, i].T for i in range(chain.shape[2])]
        ess = min(ess_bulk(c) for c in cols)
        rhat = max(rhat_rank(c) for c in cols)
        done = bool(ess >= min_ess and rhat < 1.01)
        run = IndependenceRun(chain=chain, log_prob=lp, acceptance=acc / max(tried, 1),
                              ess=float(ess), rhat=float(rhat), converged=done,
                              proposal=proposal)
        n = chain.shape[0]
        if done or n >= max_draws:
            return run
        per_draw = max(ess, 1.0) / n
        more = int(np.clip(np.ceil(1.25 * min_ess / per_draw) - n, 0.25 * n, max_draws - n))
        c2, lp2, state, a2, t2 = _extend(target, proposal, more, n_chains, gen, state)
        chain, lp = np.concatenate([chain, c2]), np.concatenate([lp, lp2])
        acc, tried = acc + a2, tried + t2
