"""Normal equations of a smooth-speed fit as a band with a few dense rows (an arrowhead).

The array's parameters are a few positions, coupled to everything, and the B-spline
coefficients of the sound speed and its gradients in time, each coupled only to the
coefficients of nearby knots: through the shots that share a knot interval, and through
correlated noise over a few correlation times. Ordered so that nearby coefficients are
adjacent (reverse Cuthill-McKee), the normal matrix of the coefficients is a band, and the
positions are its dense border. Factoring the band and the border's Schur complement costs
``O(P w^2)`` instead of the ``O(P^3)`` of a dense Cholesky (``w`` the band's half-width):
on a 14.6-hour survey with the gradients (902 parameters) a choice of the smoothing weight
evaluates the evidence some twenty times per M-step. Measurements: docs/gnssa.md, "Long
campaigns: the arrowhead".
"""

from __future__ import annotations

import functools
import threading
from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor, cho_solve, cho_solve_banded, cholesky_banded
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee

#: Entries below this fraction of the geometric mean of their diagonal are left out of the
#: band: under correlated noise the coupling of two knots falls exponentially with their
#: distance in time, and entries of 1e-20 perturb the factor far below its round-off.
DROP = 1e-20
#: Most dense (border) columns for which the arrowhead is used.
MAX_BORDER = 64
#: Fewest parameters for which the arrowhead is used (a dense Cholesky is cheaper below).
MIN_SIZE = 300
#: :func:`gram` of dense rows: an entry below this fraction of its column's norm, before the
#: column's first or after its last larger one, counts as zero. Whitened by a banded
#: factor, a coefficient's column is exactly zero before its knots and decays after them;
#: leaving out its tail changes ``J'J`` by about this fraction of ``|J_i| |J_j|``, below the
#: round-off of the dense product (``n eps``).
TAIL = 1e-17
#: Rows per block of :func:`gram`'s banded product.
CHUNK = 128


class Arrowhead:
    """Weighted sums ``A = sum_k c_k M_k`` of symmetric matrices sharing a banded pattern.

    Parameters
    ----------
    mats : sequence of numpy.ndarray
        ``(P, P)`` symmetric matrices (None entries are left out; their weight is ignored).

    Attributes
    ----------
    border : numpy.ndarray
        Indices of the dense columns (positions).
    order : numpy.ndarray
        The remaining indices, in band order.
    width : int
        The band's half-width in that order.
    size : int
        ``P``.
    keep : list of int
        The positions in ``mats`` of the matrices kept (not None).

    Raises
    ------
    ValueError
        Where the matrices have no useful arrowhead structure (use a dense factor):
        :func:`arrowhead` returns None instead.

    References
    ----------
    Golub, G. H. and Van Loan, C. F. (2013), Matrix Computations, 4th ed., sections 4.3
    (band Cholesky) and 3.2.11 (block elimination).
    """

    def __init__(self, mats):
        self.keep = [k for k, M in enumerate(mats) if M is not None]
        mats = [np.asarray(mats[k], float) for k in self.keep]
        P = mats[0].shape[0]
        if P < MIN_SIZE:
            raise ValueError(f"{P} parameters: a dense factor is cheaper")
        nz = np.zeros((P, P), bool)
        for M in mats:
            nz |= _remembered(M, "pattern", _pattern)
        key = np.packbits(nz).tobytes()
        structure = _structure(P, key)
        if isinstance(structure, str):
            raise ValueError(structure)
        border, order, width, coo, indptr = structure
        self.border, self.order, self.width, self.size = border, order, width, P
        n = order.size
        rows = np.arange(width + 1)[:, None]  # lower band storage: ab[r, c] = A[c + r, c]
        cols = np.arange(n)[None, :]
        self._valid = (cols + rows) < n
        self._r, self._c = np.broadcast_arrays(np.minimum(cols + rows, n - 1), cols)
        oi, oj = order[self._r], order[self._c]

        def parts(M):
            return (np.where(self._valid, M[oi, oj], 0.0), M[np.ix_(border, border)],
                    M[np.ix_(order, border)], np.diag(M).copy(),
                    csr_matrix((M[coo.row, coo.col], coo.col, indptr), shape=(P, P)))

        self._bands, self._bb, self._ba, self._diag, self._sparse = map(list, zip(*[
            _remembered(M, key, parts) for M in mats], strict=True))

    def quad(self, k, x):
        """Return ``x' M_k x``.

        Parameters
        ----------
        k, x
            As for :meth:`matvec`.

        Returns
        -------
        float
        """
        return float(x @ self.matvec(k, x))

    def matvec(self, k, x):
        """Return ``M_k x``.

        Parameters
        ----------
        k : int
            Index of the matrix in those given (entries below :data:`DROP` left out).
        x : numpy.ndarray
            ``(P,)``.

        Returns
        -------
        numpy.ndarray
        """
        return self._sparse[self.keep.index(k)] @ x

    def solve(self, weights, g):
        """Return ``(log|A|, A^-1 g)`` of ``A = sum_k weights[k] M_k``, or None if not positive.

        ``A`` is scaled to a unit diagonal before it is factored, as a dense factor would be.

        Parameters
        ----------
        weights : sequence of float
            One per matrix given (that of a None matrix is ignored), non-negative.
        g : numpy.ndarray
            ``(P,)`` right-hand side.

        Returns
        -------
        tuple of (float, numpy.ndarray) or None
            None where the band or the border's Schur complement is not positive definite.
        """
        factor = self.factor(weights)
        return None if factor is None else (factor.logdet, factor.solve(g))

    def factor(self, weights, damping=0.0):
        """Return a factor of ``A + damping D`` (``D`` the diagonal of ``A``), or None.

        ``A = sum_k weights[k] M_k``, scaled by ``D^-1/2`` on both sides before it is
        factored; ``damping`` is Levenberg-Marquardt's (the penalised Gauss-Newton's steps
        solve several right-hand sides with one factor).

        Parameters
        ----------
        weights : sequence of float
            As for :meth:`solve`.
        damping : float, default 0
            Non-negative.

        Returns
        -------
        ArrowheadFactor or None
            None where the band or the border's Schur complement is not positive definite.
        """
        c = [weights[k] for k in self.keep]
        d = sum(ck * dk for ck, dk in zip(c, self._diag, strict=True))
        d = np.where(d <= 0, 1.0, d)
        s = 1.0 / np.sqrt(d)
        so, sb = s[self.order], s[self.border]
        band = sum(ck * b for ck, b in zip(c, self._bands, strict=True))
        if damping:
            band[0] = band[0] + damping * d[self.order]
        band = band * so[self._r] * so[self._c]
        band[~self._valid] = 0.0
        try:
            lower = cholesky_banded(band, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            return None
        logdet = 2.0 * np.sum(np.log(lower[0])) + np.sum(np.log(d))
        Aba = Z = schur = None
        if self.border.size:
            Aba = sum(ck * m for ck, m in zip(c, self._ba, strict=True)) * so[:, None] * sb
            Abb = sum(ck * m for ck, m in zip(c, self._bb, strict=True))
            if damping:
                Abb = Abb + np.diag(damping * d[self.border])
            Abb = Abb * sb[:, None] * sb
            Z = cho_solve_banded((lower, True), Aba, check_finite=False)
            try:
                schur = cho_factor(Abb - Aba.T @ Z)
            except np.linalg.LinAlgError:
                return None
            logdet += 2.0 * np.sum(np.log(np.diag(schur[0])))
        return ArrowheadFactor(self, s, lower, Aba, Z, schur, float(logdet))


class ArrowheadFactor(NamedTuple):
    """A factor of an :class:`Arrowhead`'s sum (:meth:`Arrowhead.factor`).

    Attributes
    ----------
    head : Arrowhead
    s : numpy.ndarray
        The scaling, ``D^-1/2``.
    lower : numpy.ndarray
        The scaled band's Cholesky factor (lower band storage).
    Aba, Z : numpy.ndarray or None
        The scaled border columns and the band's solve of them (None without a border).
    schur : tuple or None
        :func:`scipy.linalg.cho_factor`'s of the border's Schur complement.
    logdet : float
        ``log|A|`` (the damped ``A`` where damped).
    """

    head: Arrowhead
    s: np.ndarray
    lower: np.ndarray
    Aba: np.ndarray | None
    Z: np.ndarray | None
    schur: tuple | None
    logdet: float

    def solve(self, g):
        """Return ``A^-1 g``.

        Parameters
        ----------
        g : numpy.ndarray
            ``(P,)``.

        Returns
        -------
        numpy.ndarray
        """
        head, s = self.head, self.s
        gs = s * np.asarray(g, float)
        x = np.empty(head.size)
        xo = cho_solve_banded((self.lower, True), gs[head.order], check_finite=False)
        if head.border.size:
            xb = cho_solve(self.schur, gs[head.border] - self.Aba.T @ xo)
            xo = xo - self.Z @ xb
            x[head.border] = xb
        x[head.order] = xo
        return s * x


#: Read-only matrices seen lately, by identity: ``id -> (matrix, {what: value})`` (at most
#: :data:`SEEN`, the least recently used dropped first: the penalties, used in every search,
#: stay; a fit decorated by :func:`forgetting` drops them when it returns).
_SEEN: dict = {}
#: How many read-only matrices :data:`_SEEN` keeps.
SEEN = 8
_SEEN_LOCK = threading.Lock()


def _remembered(M, what, make):
    """Return ``make(M)``, kept for a read-only ``M`` that owns its data.

    The same object holds the same values unless its flag is turned back, which the package
    never does. A fit chooses the speed's and the gradients' weights in turn on one read-only
    ``J'J`` (:func:`~.array.normal_equations`) and its read-only penalties: each search's
    arrowhead reuses their patterns and band parts. A writeable matrix, or a view (whose base may be
    written), is never kept. Fits in several threads share :data:`_SEEN` under a lock.
    """
    if M.flags.writeable or M.base is not None:
        return make(M)
    with _SEEN_LOCK:
        entry = _SEEN.pop(id(M), None)  # put back last: the least recently used goes first
        if entry is None or entry[0] is not M:
            entry = (M, {})
        _SEEN[id(M)] = entry
        while len(_SEEN) > SEEN:
            _SEEN.pop(next(iter(_SEEN)))
        value = entry[1].get(what)
    if value is None:
        value = make(M)
        with _SEEN_LOCK:
            entry[1][what] = value
    return value


def forgetting(func):
    """Decorate a fit: the matrices :func:`_remembered` kept are dropped when it returns.

    Parameters
    ----------
    func : callable
        The fit (:func:`~bayes_mpem.survey_in.array.locate_array`).

    Returns
    -------
    callable
        ``func``, clearing the kept matrices on return or on an exception.
    """

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        finally:
            with _SEEN_LOCK:
                _SEEN.clear()

    return wrapper


def _pattern(M):
    """Return where ``|M| > DROP sqrt(|M_ii M_jj|)`` (any non-zero where a diagonal is 0).

    A penalty has a few non-zero entries: they alone are tested. ``J'J`` under correlated
    noise is dense: tested in place, the build's largest passes.
    """
    nz = np.zeros(M.shape, bool)
    d = np.sqrt(np.abs(np.diag(M)))
    if np.count_nonzero(M) <= 0.05 * M.size:
        flat = np.flatnonzero(M)
        i, j = np.divmod(flat, M.shape[1])
        dd = d[i] * d[j]
        keep = (np.abs(M.ravel()[flat]) > DROP * dd) | (dd == 0)
        nz[i[keep], j[keep]] = True
        return nz
    thr = np.multiply.outer(d, d)
    thr *= DROP
    np.greater(np.abs(M), thr, out=nz)
    zero = np.flatnonzero(d == 0)
    if zero.size:  # NaN entries of a row without a diagonal (finite ones are counted above)
        nz[zero] |= M[zero] != 0
        nz[:, zero] |= M[:, zero] != 0
    return nz


@functools.lru_cache(maxsize=8)
def _structure(P, packed):
    """Border, band order, half-width, the pattern (COO) and its CSR row pointers, or why not.

    A fit builds arrowheads of the same few patterns again and again (the speed's and the
    gradients' weights are chosen in turn on one ``J'J``): the ordering is kept.
    """
    nz = np.unpackbits(np.frombuffer(packed, np.uint8), count=P * P).astype(bool)
    pattern = csr_matrix(nz.reshape(P, P))
    count = np.diff(pattern.indptr)
    border = np.flatnonzero(count > max(4 * np.median(count), 40))
    if border.size > MAX_BORDER:
        return f"{border.size} dense columns"
    rest = np.setdiff1d(np.arange(P), border)
    order = rest[reverse_cuthill_mckee(pattern[rest][:, rest], symmetric_mode=True)]
    where = np.full(P, -1)
    where[order] = np.arange(order.size)
    coo = pattern.tocoo()
    inner = (where[coo.row] >= 0) & (where[coo.col] >= 0)
    width = int(np.abs(where[coo.row] - where[coo.col])[inner].max()) if inner.any() else 0
    if (width + 1) * 4 > order.size:
        return f"a band of half-width {width} in {order.size}"
    for a in (border, order, coo.row, coo.col, pattern.indptr):
        a.setflags(write=False)
    return border, order, width, coo, pattern.indptr  # coo: in the CSR's (row, column) order


def gram(J):
    """Return ``J'J``, through a sparse or a banded product where ``J`` allows.

    A shot's row of the Jacobian touches its transponder's position and the four B-spline
    coefficients of each series about its time: about 3 % of a long survey's columns, a
    sparse product. Whitened under correlated noise (rows in time order) the rows are
    dense, but each coefficient's column is zero before its knots and falls below
    :data:`TAIL` of its norm some correlation times after them: the product is then
    summed over blocks of :data:`CHUNK` rows, each over the columns alive in it. Dense
    otherwise.

    Parameters
    ----------
    J : numpy.ndarray
        ``(n, P)``.

    Returns
    -------
    numpy.ndarray
        ``(P, P)``, symmetric.
    """
    J = np.asarray(J, float)
    if J.shape[1] < MIN_SIZE:
        return J.T @ J
    if np.count_nonzero(J) <= 0.1 * J.size:  # (a count is cheap; the indices of a dense J not)
        flat = np.flatnonzero(J)  # row by row: already a CSR's order (no sort)
        rows, cols = np.divmod(flat, J.shape[1])
        indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=J.shape[0]))])
        S = csr_matrix((J.ravel()[flat], cols, indptr), shape=J.shape)
        return (S.T @ S).toarray()
    out = _banded_gram(J)
    return J.T @ J if out is None else out


def _banded_gram(J):
    """:func:`gram` by blocks of rows over their live columns; None where not cheaper."""
    n, P = J.shape
    norm = np.sqrt(np.einsum("ij,ij->j", J, J))
    if not np.isfinite(norm).all():  # NaN, inf or overflow: the dense product propagates it
        return None
    live = np.abs(J) > TAIL * norm
    some = live.any(axis=0)
    first = np.where(some, live.argmax(axis=0), n)
    last = np.where(some, n - 1 - live[::-1].argmax(axis=0), -1)
    plan, cost = [], 0
    for a in range(0, n, CHUNK):
        b = min(a + CHUNK, n)
        cols = np.flatnonzero((first < b) & (last >= a))
        plan.append((a, b, cols))
        cost += (b - a) * cols.size**2
    if cost > 0.25 * n * P * P:
        return None
    G = np.zeros((P, P))
    for a, b, cols in plan:
        B = J[a:b, cols]
        G[np.ix_(cols, cols)] += B.T @ B
    return G


def arrowhead(mats):
    """Return an :class:`Arrowhead` of ``mats``, or None where a dense factor is the better.

    Parameters
    ----------
    mats : sequence of numpy.ndarray or None
        ``(P, P)`` symmetric positive semi-definite matrices whose non-negative weighted sums
        will be factored (the data's ``J'J``, the penalties); None entries are left out.

    Returns
    -------
    Arrowhead or None
        None below :data:`MIN_SIZE` parameters, with more than :data:`MAX_BORDER` dense
        columns, or with a band wider than a quarter of the coefficients.

    Examples
    --------
    >>> import numpy as np
    >>> P = 400
    >>> M = 4 * np.eye(P) - np.eye(P, k=1) - np.eye(P, k=-1)
    >>> M[0, :] = M[:, 0] = 0.1; M[0, 0] = P
    >>> a = arrowhead([M])
    >>> a.border.tolist(), a.width
    ([0], 1)
    >>> logdet, x = a.solve([1.0], np.ones(P))
    >>> bool(np.allclose(M @ x, 1.0)), bool(np.isclose(logdet, np.linalg.slogdet(M)[1]))
    (True, True)
    """
    try:
        return Arrowhead(mats)
    except ValueError:
        return None
