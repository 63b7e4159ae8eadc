"""The arrowhead factor of the smooth-speed normal equations agrees with the dense one."""

import numpy as np
import pandas as pd
import pytest
from scipy.linalg import block_diag, cholesky, solve_triangular

from bayes_mpem.survey_in import array as arr
from bayes_mpem.survey_in.arrowhead import arrowhead, gram
from bayes_mpem.survey_in.travel_times import speed_basis, speed_penalty


def _problem(n=1500, intervals=70, tau=0.0, seed=0):
    """A GNSS-A-like Jacobian: 4 transponders' positions, then 5 spline series in time.

    ``tau`` > 0 whitens the rows under an exponential correlation of that many knot
    spacings, as correlated noise does (dense rows, a band that decays instead of ending).
    """
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 36000.0, n))
    B = speed_basis(pd.DataFrame({"time": t}), intervals, (0.0, 36000.0))
    k = rng.integers(0, 4, n)
    pos = np.zeros((n, 12))
    pos[np.arange(n)[:, None], 3 * k[:, None] + np.arange(3)] = rng.normal(0, 1, (n, 3))
    series = [B * (1e3 if s == 0 else rng.normal(0, 3e2, (n, 1))) for s in range(5)]
    J = np.hstack([pos, *series])
    r = rng.normal(0, 1e-4, n)
    if tau > 0:
        dt = np.abs(t[:, None] - t[None, :]) / (tau * 36000.0 / intervals)
        L = cholesky(0.3 * np.eye(n) + 0.7 * np.exp(-dt), lower=True)
        J, r = solve_triangular(L, J, lower=True), solve_triangular(L, r, lower=True)
    S = speed_penalty(intervals, (0.0, 36000.0))
    m = S.shape[0]
    H = block_diag(np.zeros((12, 12)), S, np.zeros((4 * m, 4 * m)))
    Hg = block_diag(np.zeros((12 + m, 12 + m)), *[S] * 4)
    theta = np.concatenate([rng.normal(0, 1, 12), 1 + rng.normal(0, 1e-6, m),
                            rng.normal(0, 1e-7, 4 * m)])
    return J, r, theta, H, Hg


@pytest.mark.parametrize("tau", [0.0, 0.6])
def test_evidence_curve_is_the_dense_log_evidence(tau):
    J, r, theta, H, Hg = _problem(tau=tau)
    sigma = 1e-4
    for Hf in (None, 1e9 * Hg):
        pre = (gram(J), J.T @ r, float(r @ r))
        blocks = arr.null_blocks(H, Hf)
        rank = arr._penalty_rank(H)
        structure = arrowhead([pre[0], H, Hf])
        assert structure is not None and structure.border.size == 12
        assert structure.width < (60 if tau else 25), structure.width
        curve = arr.evidence_curve(pre, theta, H, sigma, rank, Hf, blocks)
        for lam in 10.0 ** np.arange(0.0, 14.0, 1.5):
            dense = arr.log_evidence(pre, r, theta, H, sigma, lam, rank, Hf, blocks)[0]
            assert np.isfinite(dense)
            assert curve(lam) == pytest.approx(dense, abs=1e-6, rel=1e-12), lam


def test_the_arrowhead_solves_and_refuses_what_the_dense_factor_does():
    J, r, theta, H, Hg = _problem(tau=0.6, seed=1)
    JtJ = J.T @ J
    a = arrowhead([JtJ, H, Hg])
    g = np.random.default_rng(2).normal(size=JtJ.shape[0])
    for w in ([1e8, 1e3, 1e5], [1.0, 1e12, 1e-3]):
        A = w[0] * JtJ + w[1] * H + w[2] * Hg
        logdet, x = a.solve(w, g)
        s = 1 / np.sqrt(np.diag(A))
        want = s * np.linalg.solve(A * s[:, None] * s, s * g)
        np.testing.assert_allclose(x, want, rtol=1e-7, atol=1e-9 * np.abs(want).max())
        assert logdet == pytest.approx(np.linalg.slogdet(A)[1] , abs=1e-6)
    # a matrix that is not positive definite is refused, as the dense factor refuses it
    B = JtJ.copy()
    B[20, :] = B[:, 20] = 0.0
    B[20, 20] = -1.0
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(B)
    assert arrowhead([B, H]).solve([1.0, 0.0], g) is None


def test_a_damped_factor_solves_the_levenberg_marquardt_system():
    J, r, theta, H, Hg = _problem(tau=0.6, seed=3)
    JtJ = J.T @ J
    Q = 1e3 * H + 1e5 * Hg
    a = arrowhead([JtJ, Q])
    A = JtJ + Q
    d = np.diag(A)
    s = 1 / np.sqrt(d)
    g = np.random.default_rng(4).normal(size=d.size)
    for mu in (0.0, 1e-6, 1e-2, 10.0):
        solve = arr._damped_solver(A, d, s, mu, a)
        want = arr._damped_solver(A, d, s, mu)(g)  # the dense factor
        np.testing.assert_allclose(solve(g), want, rtol=1e-7, atol=1e-9 * np.abs(want).max())
        M = (A + mu * np.diag(d)) * s[:, None] * s
        assert a.factor([1.0, 1.0], mu).logdet == pytest.approx(
            np.linalg.slogdet(M)[1] + np.sum(np.log(d)), abs=1e-6)
    assert np.linalg.norm(arr._damped_solver(A, d, s, 10.0, a)(g) * np.sqrt(d)) < (
        np.linalg.norm(arr._damped_solver(A, d, s, 0.0, a)(g) * np.sqrt(d)))  # damped: shorter


def test_gauss_newton_steps_on_the_arrowhead(monkeypatch):
    J, r, theta, H, Hg = _problem(seed=5)
    Q = 1e-2 * H + 1.0 * Hg  # the residuals' scale is 1e-4
    heads = []
    solver = arr._damped_solver
    monkeypatch.setattr(arr, "_damped_solver",
                        lambda *a: heads.append(a[-1] is not None) or solver(*a))
    th = arr.penalised_gauss_newton(lambda t: r + J @ (t - theta), lambda t: J, theta, Q)
    assert heads and all(heads)
    A = J.T @ J + Q  # a linear problem: one step to the normal equations' solution
    want = theta - np.linalg.solve(A, J.T @ r + Q @ arr.null_shifted(theta, Q))
    np.testing.assert_allclose(th, want, rtol=1e-6, atol=1e-6 * np.abs(want - theta).max())


def test_no_arrowhead_where_a_dense_factor_is_better():
    J, r, theta, H, Hg = _problem(n=400, intervals=10)  # 77 parameters
    assert arrowhead([J.T @ J, H]) is None
    M = np.random.default_rng(0).normal(size=(400, 400))
    assert arrowhead([M @ M.T]) is None  # no band


def test_gram_is_j_transpose_j():
    J, r, theta, H, Hg = _problem(n=800, intervals=70)
    np.testing.assert_allclose(gram(J), J.T @ J, rtol=1e-12, atol=1e-12 * np.abs(J).max() ** 2)


@pytest.mark.parametrize("tau", [0.1, 0.6, 3.0])
def test_gram_of_whitened_rows_is_j_transpose_j_to_round_off(tau, monkeypatch):
    """Dense rows whose columns decay: blocks of rows over their live columns."""
    from bayes_mpem.survey_in import arrowhead as ah

    Jw = _problem(n=800, intervals=70, tau=tau)[0]
    dense = Jw.T @ Jw
    d = np.sqrt(np.diag(dense))
    assert ah._banded_gram(Jw) is not None  # the banded product is the one tested
    assert np.abs((gram(Jw) - dense) / np.outer(d, d)).max() < 1e-13
    monkeypatch.setattr(ah, "TAIL", 1e-3)  # the test can fail: a tail that matters
    assert np.abs((gram(Jw) - dense) / np.outer(d, d)).max() > 1e-6


def test_choose_smoothing_reports_the_evidence_at_its_weight():
    J, r, theta, H, Hg = _problem(tau=0.6)
    lam, ll = arr.choose_smoothing(J, r, theta, H, 1e-4, None, 1e9 * Hg, with_evidence=True)
    assert lam == arr.choose_smoothing(J, r, theta, H, 1e-4, None, 1e9 * Hg)
    dense = arr.log_evidence(J, r, theta, H, 1e-4, lam, None, 1e9 * Hg)[0]
    assert ll == pytest.approx(dense, abs=1e-6)


def test_the_grid_leaves_out_only_weights_without_a_share(monkeypatch):
    J, r, theta, H, Hg = _problem(tau=0.6)
    lam = arr.choose_smoothing(J, r, theta, H, 1e-4, None, 1e9 * Hg)
    meat = gram(J) / 1e-8
    args = (J, r, theta, H, 1e-4, lam, 1e9 * Hg, meat, 500, arr.WEIGHT_GRID)
    w, cov, spread, rows, ll, _ = arr._grid_average(*args)
    assert any(row is None for row in rows)  # a sharp evidence: some left out
    assert rows[int(np.argmin(np.abs(arr.WEIGHT_GRID)))] is not None
    monkeypatch.setattr(arr, "GRID_SHARE", 0.0)
    w0, cov0, spread0, rows0, ll0, _ = arr._grid_average(*args)
    assert all(row is not None for row in rows0)
    np.testing.assert_allclose(w, w0)
    d = np.sqrt(np.diag(cov0))  # the weights left out hold 7.6e-8 of the average here
    assert np.abs((cov - cov0) / np.outer(d, d)).max() < 1e-7  # 2.1e-8 measured
    assert np.abs((spread - spread0) / np.outer(d, d)).max() < 1e-7


def test_the_grid_leaves_out_the_smallest_shares_up_to_their_total():
    w = np.array([0.5, 4e-5, 0.49989, 5e-5, 2e-5, 0.0, np.nan])
    assert arr._grid_used(w).tolist() == [True, False, True, True, False, False, False]
    gen = np.random.default_rng(4)
    for _ in range(200):
        w = np.exp(-gen.exponential(8.0, 17))
        w /= w.sum()
        used = arr._grid_used(w)
        assert w[~used].sum() < arr.GRID_SHARE  # the left-out total is bounded
        if used.any():  # and no more could go: the smallest used share would cross it
            assert w[~used].sum() + w[used].min() >= arr.GRID_SHARE


def test_the_grid_computes_its_middle_row_even_without_a_share():
    J, r, theta, H, Hg = _problem(tau=0.6)
    lam = arr.choose_smoothing(J, r, theta, H, 1e-4, None, 1e9 * Hg)
    args = (J, r, theta, H, 1e-4, 10 * lam, 1e9 * Hg, gram(J) / 1e-8, 500, arr.WEIGHT_GRID)
    w, cov, spread, rows, ll, _ = arr._grid_average(*args)
    mid = int(np.argmin(np.abs(arr.WEIGHT_GRID)))
    assert w[mid] < 1e-12 and rows[mid] is not None  # the caller reads it


def test_a_grid_without_a_finite_evidence_gives_nan_not_zero():
    J, r, theta, H, Hg = _problem(tau=0.0)
    J[:, 0] = 0.0  # a position the data do not touch: every weight's matrix is singular
    args = (J, r, theta, H, 1e-4, 1e6, 1e9 * Hg, gram(J) / 1e-8, 500, arr.WEIGHT_GRID)
    w, cov, spread, rows, ll, _ = arr._grid_average(*args)
    assert np.all(np.isinf(ll))
    assert cov.shape == spread.shape == (theta.size, theta.size)
    assert np.isnan(cov).all() and np.isnan(spread).all()


def test_read_only_matrices_lend_their_parts_and_writeable_ones_never():
    from bayes_mpem.survey_in import arrowhead as ah

    J, r, theta, H, Hg = _problem(tau=0.6)
    JtJ = gram(J)
    fresh = arrowhead([JtJ, H, 1e9 * Hg])
    g = np.linspace(-1.0, 1.0, JtJ.shape[0])
    ah._SEEN.clear()
    assert arrowhead([JtJ, H, 1e9 * Hg]) is not None and not ah._SEEN  # writeable: not kept
    JtJ.flags.writeable = H.flags.writeable = False
    first = arrowhead([JtJ, H, 1e9 * Hg])
    assert {id(JtJ), id(H)} <= set(ah._SEEN)
    again = arrowhead([JtJ, Hg, 1e7 * H])  # the other weight's search on the same J'J
    assert np.array_equal(first.solve([1e8, 1e3, 1.0], g)[1], fresh.solve([1e8, 1e3, 1.0], g)[1])
    assert np.array_equal(again.solve([1e8, 1e9, 1.0], g)[1],
                          arrowhead([JtJ.copy(), Hg.copy(), 1e7 * H]).solve([1e8, 1e9, 1.0],
                                                                            g)[1])
    assert len(ah._SEEN) <= ah.SEEN
    ah._SEEN.clear()


def test_a_fit_forgets_the_matrices_it_lent():
    from bayes_mpem.survey_in import arrowhead as ah
    from bayes_mpem.survey_in.array_survey import locate_array_survey
    from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa

    raw = simulate_gnssa(hours=6, rng=0, speed_model="field", track="star+circle",
                         gradients=True).raw()  # 377 parameters: arrowheads
    seen = []
    real = ah._remembered

    def spy(M, what, make):
        seen.append(M.flags.writeable)
        return real(M, what, make)

    try:
        ah._remembered = spy
        locate_array_survey(raw)
    finally:
        ah._remembered = real
    assert not all(seen)  # the fit's J'J and penalties were read-only, and kept ...
    assert not ah._SEEN  # ... until it returned


def test_a_view_of_a_writeable_matrix_is_never_kept():
    from bayes_mpem.survey_in import arrowhead as ah

    P = 400
    base = 4 * np.eye(P) - np.eye(P, k=1) - np.eye(P, k=-1)
    base[0, :] = base[:, 0] = 0.1
    base[0, 0] = P
    M = base.view()
    M.flags.writeable = False
    ah._SEEN.clear()
    arrowhead([M])
    base *= 2  # its owner changes it
    x = arrowhead([M]).solve([1.0], np.ones(P))[1]
    assert np.allclose(M @ x, 1.0) and not ah._SEEN


def test_the_penalty_rank_reads_any_number_type():
    H = np.array([[0, 0, 0], [0, 2, -2], [0, -2, 2]])
    assert arr._penalty_rank(H) == arr._penalty_rank(H.astype(np.float32)) == 1
