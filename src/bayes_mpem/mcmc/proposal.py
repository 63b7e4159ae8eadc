"""A Laplace (Student-t) proposal for independence Metropolis-Hastings (``docs/bayes.md``)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


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
        gen : numpy.random.Generator or numpy.random.RandomState

        Returns
        -------
        numpy.ndarray
            ``(n, ndim)``.
        """
        d = self.centre.size
        z = gen.standard_normal((n, d)) @ self.chol.T
        return self.centre + z * np.sqrt(self.df / gen.chisquare(self.df, size=n))[:, None]

    @cached_property
    def _inv_chol_t(self) -> np.ndarray:
        """The transposed inverse of :attr:`chol`."""
        return np.linalg.inv(self.chol).T

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
        r = (np.atleast_2d(u) - self.centre) @ self._inv_chol_t
        return -0.5 * (self.df + self.centre.size) * np.log1p(
            np.einsum("ij,ij->i", r, r) / self.df)


#: step lengths tried by the line search: du, du / 2, ..., du / 2**(_HALVINGS - 1)
_HALVINGS = 10


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

    References
    ----------
    Mengersen, K. L. and Tweedie, R. L. (1996). Rates of convergence of the Hastings and
    Metropolis algorithms. Annals of Statistics 24(1), 101-121 (uniform ergodicity when
    ``p / q`` is bounded, as with heavier-tailed proposals).

    Examples
    --------
    >>> target = lambda u: -0.5 * ((u - 1.0) ** 2 / np.array([1.0, 4.0])).sum(axis=1)
    >>> q = laplace_proposal(target, [0.0, 0.0], [1.0, 1.0])
    >>> q.centre.round(6).tolist(), (q.chol @ q.chol.T).round(6).tolist()
    ([1.0, 1.0], [[1.0, 0.0], [0.0, 4.0]])
    """
    u = np.asarray(start, dtype=float).copy()
    h = 0.25 * np.asarray(step, dtype=float)
    v = target(_hessian_points(u, h))
    for it in range(newton + 1):
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
        # the first of the steps du, du / 2, ..., du / 512 that does not lower the density,
        # in one call with the difference points around u + du (the usual next centre)
        pts = _hessian_points(u + du, h)
        steps = du / 2.0 ** np.arange(1, _HALVINGS)[:, None]
        w = target(np.vstack([pts, u + steps]))
        cand = np.concatenate([w[:1], w[len(pts):]])  # at u + du, u + du / 2, ...
        ok = np.flatnonzero(np.isfinite(cand) & (cand >= v[0] - 1e-9))
        if ok.size and ok[0] == 0:
            u, v = u + du, w[:len(pts)]
        else:
            if ok.size:
                u = u + steps[ok[0] - 1]
            v = target(_hessian_points(u, h))
    return TProposal(centre=u, chol=np.linalg.cholesky(cov), df=float(df))
