"""Sparse normal equations of a track: banded solve, Schur complement, selected inversion.

The method: ``docs/navigate.md`` (*The estimator*).

Examples
--------
Two epochs, no global unknown:

>>> import numpy as np
>>> ne = Normal(diag=np.array([[2.0, 0.0, 2.0], [2.0, 0.0, 2.0]]), lam=np.array([1.0]),
...             B=np.zeros((4, 0)), C=np.zeros((0, 0)), grad_p=np.array([-1.0, 0, 0, 0]),
...             grad_g=np.zeros(0))
>>> step = solve(ne)
>>> np.round(step.dp[:, 0], 6).tolist()
[0.666667, 0.333333]
>>> np.round(marginal_covariances(ne, step)[:, 0, 0], 6).tolist()
[0.666667, 0.666667]
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded


class Normal(NamedTuple):
    """The Gauss-Newton normal equations ``H delta = -grad``.

    Attributes
    ----------
    diag : numpy.ndarray
        ``(K, 3)`` the 2x2 diagonal blocks of the track part, as ``(a, b, c)``
        for ``[[a, b], [b, c]]``.
    lam : numpy.ndarray
        ``(K - 1,)`` the off-diagonal blocks are ``-lam[k] I`` (between epochs
        ``k`` and ``k + 1``).
    B : numpy.ndarray
        ``(2K, G)`` coupling of the track (``x_1, y_1, x_2, ...``) with the globals.
    C : numpy.ndarray
        ``(G, G)`` the globals' block.
    grad_p : numpy.ndarray
        ``(2K,)`` gradient of the objective with respect to the track.
    grad_g : numpy.ndarray
        ``(G,)`` gradient with respect to the globals.
    """

    diag: np.ndarray
    lam: np.ndarray
    B: np.ndarray
    C: np.ndarray
    grad_p: np.ndarray
    grad_g: np.ndarray


class Step(NamedTuple):
    """The solution of :func:`solve`, with what the covariances need.

    Attributes
    ----------
    dp : numpy.ndarray
        ``(K, 2)`` step of the track.
    dg : numpy.ndarray
        ``(G,)`` step of the globals.
    X : numpy.ndarray
        ``(2K, G)`` ``A^{-1} B``.
    S : numpy.ndarray
        ``(G, G)`` Schur complement ``C - B^T A^{-1} B``.
    """

    dp: np.ndarray
    dg: np.ndarray
    X: np.ndarray
    S: np.ndarray


def band(diag, lam) -> np.ndarray:
    """Store the track block ``A`` in LAPACK's lower band storage (bandwidth 2).

    Parameters
    ----------
    diag : numpy.ndarray
        ``(K, 3)`` diagonal blocks ``(a, b, c)``.
    lam : numpy.ndarray
        ``(K - 1,)`` off-diagonal weights.

    Returns
    -------
    numpy.ndarray
        ``(3, 2K)``: row 0 the diagonal, row ``d`` the entries ``A[j + d, j]``.

    Examples
    --------
    >>> band(np.array([[1.0, 0.5, 2.0], [3.0, 0.0, 4.0]]), np.array([0.25])).tolist()
    [[1.0, 2.0, 3.0, 4.0], [0.5, 0.0, 0.0, 0.0], [-0.25, -0.25, 0.0, 0.0]]
    """
    k = diag.shape[0]
    ab = np.zeros((3, 2 * k))
    ab[0, 0::2], ab[0, 1::2] = diag[:, 0], diag[:, 2]
    ab[1, 0::2] = diag[:, 1]
    ab[2, 0:2 * k - 2:2] = -lam
    ab[2, 1:2 * k - 2:2] = -lam
    return ab


def _mat(B, X):
    """``B^T X`` without BLAS (a threaded BLAS spin-waits on a busy 2-core machine)."""
    return np.einsum("ig,ih->gh", B, X)


def solve(ne: Normal) -> Step:
    """Solve the normal equations, the globals eliminated by the Schur complement.

    Raises
    ------
    numpy.linalg.LinAlgError
        When ``A`` or the Schur complement is not positive definite.
    """
    k = ne.diag.shape[0]
    cb = cholesky_banded(band(ne.diag, ne.lam), lower=True)
    rhs = np.column_stack([-ne.grad_p, ne.B])
    sol = cho_solve_banded((cb, True), rhs)
    y, X = sol[:, 0], sol[:, 1:]
    S = ne.C - _mat(ne.B, X)
    g = ne.B.shape[1]
    dg = np.linalg.solve(S, -ne.grad_g - np.einsum("ig,i->g", ne.B, y)) if g else np.zeros(0)
    dp = y - np.einsum("ig,g->i", X, dg)
    return Step(dp.reshape(k, 2), dg, X, S)


def solve_columns(ne: Normal, step: Step, rhs_p, rhs_g):
    """Solve ``H [x; y] = [rhs_p; rhs_g]`` for several right-hand sides at once.

    The same block elimination as :func:`solve`, reusing its ``X`` and Schur complement.

    Parameters
    ----------
    step : Step
        :func:`solve` of ``ne``.
    rhs_p : numpy.ndarray
        ``(2K, m)`` track part of the right-hand sides.
    rhs_g : numpy.ndarray
        ``(G, m)`` globals' part.

    Returns
    -------
    x : numpy.ndarray
        ``(2K, m)``.
    y : numpy.ndarray
        ``(G, m)``.

    Raises
    ------
    numpy.linalg.LinAlgError
        When ``A`` is not positive definite.

    Examples
    --------
    >>> ne = Normal(diag=np.array([[2.0, 0.0, 2.0]]), lam=np.zeros(0), B=np.array([[1.0], [0.0]]),
    ...             C=np.array([[2.0]]), grad_p=np.zeros(2), grad_g=np.zeros(1))
    >>> x, y = solve_columns(ne, solve(ne), np.array([[1.0], [0.0]]), np.array([[0.0]]))
    >>> H = np.array([[2.0, 0, 1], [0, 2, 0], [1, 0, 2]])
    >>> bool(np.allclose(np.r_[x[:, 0], y[:, 0]], np.linalg.solve(H, [1.0, 0, 0])))
    True
    """
    cb = cholesky_banded(band(ne.diag, ne.lam), lower=True)
    Y = cho_solve_banded((cb, True), rhs_p)
    if not step.S.size:
        return Y, np.zeros((0, rhs_p.shape[1]))
    y = np.linalg.solve(step.S, rhs_g - _mat(ne.B, Y))
    return Y - np.einsum("ig,gm->im", step.X, y), y


def _track_inverse_blocks(diag, lam) -> np.ndarray:
    """Diagonal 2x2 blocks of ``A^{-1}`` by the forward-backward block recursion.

    Forward: ``S_1 = D_1``, ``S_k = D_k - lam_{k-1}^2 S_{k-1}^{-1}``; backward:
    ``Sigma_K = S_K^{-1}``, ``Sigma_k = S_k^{-1} + lam_k^2 S_k^{-1} Sigma_{k+1} S_k^{-1}``.
    Python floats: the recursion is sequential and 2x2, where NumPy calls cost more
    than the arithmetic.
    """
    k = diag.shape[0]
    a_, b_, c_ = (diag[:, j].tolist() for j in range(3))
    lam2 = (np.asarray(lam) ** 2).tolist()
    inv = [None] * k
    pa = pb = pc = 0.0
    for i in range(k):
        a, b, c = a_[i], b_[i], c_[i]
        if i:
            w = lam2[i - 1]
            a, b, c = a - w * pa, b - w * pb, c - w * pc
        det = a * c - b * b
        pa, pb, pc = c / det, -b / det, a / det
        inv[i] = (pa, pb, pc)
    out = np.empty((k, 3))
    x, y, w_ = inv[-1]
    out[-1] = x, y, w_
    for i in range(k - 2, -1, -1):
        p, q, r = inv[i]
        m = lam2[i]
        u0, u1 = p * x + q * y, p * y + q * w_
        v0, v1 = q * x + r * y, q * y + r * w_
        x, y, w_ = p + m * (u0 * p + u1 * q), q + m * (u0 * q + u1 * r), r + m * (v0 * q + v1 * r)
        out[i] = x, y, w_
    return out


def marginal_covariances(ne: Normal, step: Step) -> np.ndarray:
    """Return the 2x2 covariance of every epoch: diagonal blocks of the inverse of the full system.

    Parameters
    ----------
    ne : Normal
        The normal equations (the Hessian of the objective, Gauss-Newton).
    step : Step
        Their :func:`solve` (for ``X = A^{-1} B`` and the Schur complement).

    Returns
    -------
    numpy.ndarray
        ``(K, 2, 2)``: ``[A^{-1}]_kk + X_k S^{-1} X_k^T``.
    """
    blocks = _track_inverse_blocks(ne.diag, ne.lam)
    k = blocks.shape[0]
    cov = np.empty((k, 2, 2))
    cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1] = blocks[:, 0], blocks[:, 1], blocks[:, 2]
    cov[:, 1, 0] = blocks[:, 1]
    if step.S.size:
        Xk = step.X.reshape(k, 2, -1)
        cov += np.einsum("kag,gh,kbh->kab", Xk, np.linalg.inv(step.S), Xk)
    return cov


def global_covariance(step: Step) -> np.ndarray:
    """Covariance of the global unknowns: the inverse of the Schur complement.

    Returns
    -------
    numpy.ndarray
        ``(G, G)``.
    """
    return np.linalg.inv(step.S) if step.S.size else np.zeros((0, 0))


def cross_covariances(step: Step) -> np.ndarray:
    """Return the covariance of every epoch's position with the globals: ``-X_k S^{-1}``.

    The off-diagonal block of the inverse of ``[[A, B], [B^T, C]]`` is
    ``-A^{-1} B S^{-1}``; its rows of epoch ``k`` are ``Cov(p_k, g)``.

    Returns
    -------
    numpy.ndarray
        ``(K, 2, G)``.

    Examples
    --------
    One epoch, one global, ``H = [[2, 0, 1], [0, 2, 0], [1, 0, 2]]``:

    >>> ne = Normal(diag=np.array([[2.0, 0.0, 2.0]]), lam=np.zeros(0), B=np.array([[1.0], [0.0]]),
    ...             C=np.array([[2.0]]), grad_p=np.zeros(2), grad_g=np.zeros(1))
    >>> H = np.array([[2.0, 0, 1], [0, 2, 0], [1, 0, 2]])
    >>> bool(np.allclose(cross_covariances(solve(ne))[0], np.linalg.inv(H)[:2, 2:]))
    True
    """
    k = step.dp.shape[0]
    return -np.einsum("ig,gh->ih", step.X, global_covariance(step)).reshape(k, 2, -1)
