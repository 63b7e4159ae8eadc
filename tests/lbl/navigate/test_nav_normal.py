"""The sparse solve, the selected inversion and the normal equations of the objective."""

import numpy as np
import pytest

from bayes_mpem.lbl.navigate.dive import build_dive
from bayes_mpem.lbl.navigate.normal import (
    Normal,
    band,
    cross_covariances,
    global_covariance,
    marginal_covariances,
    solve,
    solve_columns,
)
from bayes_mpem.lbl.navigate.objective import (
    Priors,
    State,
    missing_information,
    normal_equations,
    objective,
    predictions,
)
from bayes_mpem.lbl.navigate.simulate import simulate_dive


def _random_system(k, g, seed):
    rng = np.random.default_rng(seed)
    m = rng.normal(size=(k, 2, 2))
    blocks = m @ m.transpose(0, 2, 1) + 0.1 * np.eye(2)
    lam = rng.uniform(0.1, 5.0, k - 1)
    diag = np.column_stack([blocks[:, 0, 0], blocks[:, 0, 1], blocks[:, 1, 1]])
    diag[:-1, [0, 2]] += lam[:, None]
    diag[1:, [0, 2]] += lam[:, None]
    B = rng.normal(size=(2 * k, g))
    C = B.T @ B + np.eye(g) * 3.0
    ne = Normal(diag, lam, B, C, rng.normal(size=2 * k), rng.normal(size=g))
    H = np.zeros((2 * k + g, 2 * k + g))
    ab = band(diag, lam)
    for d in range(3):
        for j in range(2 * k - d):
            H[j + d, j] = H[j, j + d] = ab[d, j]
    H[:2 * k, 2 * k:], H[2 * k:, :2 * k], H[2 * k:, 2 * k:] = B, B.T, C
    return ne, H


@pytest.mark.parametrize(("k", "g"), [(1, 0), (7, 0), (30, 3), (200, 6)])
def test_schur_solve_and_covariances_match_the_dense_system(k, g):
    ne, H = _random_system(k, g, seed=k + g)
    step = solve(ne)
    dense = np.linalg.solve(H, -np.concatenate([ne.grad_p, ne.grad_g]))
    np.testing.assert_allclose(np.concatenate([step.dp.ravel(), step.dg]), dense, atol=1e-9)
    inv = np.linalg.inv(H)
    cov = marginal_covariances(ne, step)
    for i in range(k):
        np.testing.assert_allclose(cov[i], inv[2 * i:2 * i + 2, 2 * i:2 * i + 2], atol=1e-9)
    np.testing.assert_allclose(global_covariance(step), inv[2 * k:, 2 * k:], atol=1e-9)
    cross = cross_covariances(step)
    assert cross.shape == (k, 2, g)
    np.testing.assert_allclose(cross.reshape(2 * k, g), inv[:2 * k, 2 * k:], atol=1e-9)


def test_normal_equations_are_the_gradient_and_gauss_newton_hessian_of_the_objective():
    sim = simulate_dive("abe58", rng=0, n_cycles=25)
    dive = build_dive(sim.survey)
    k, nb = dive.n_epochs, len(dive.beacon_ids)
    rng = np.random.default_rng(1)
    st = State(dive.dr + rng.normal(0, 5, (k, 2)), 0.02, 1.01,
               dive.beacon_xyz[:, 2] + rng.normal(0, 3, nb), np.array([False, True, False, True]),
               4.0, np.full(nb, 8.0), np.full((nb, 3), 1 / 3))
    a, b = rng.random(dive.n) / 16, rng.random(dive.n) / 64
    pri = Priors(0.1, 100.0, 0.1, 0.05, 1000.0)
    free = (0, 1, 3)
    ne = normal_equations(dive, st, a, b, pri, free)

    def at(x):
        d0 = st.d0.copy()
        d0[list(free)] = x[2 * k + 2:]
        return objective(dive, st, a, b, pri, track=x[:2 * k].reshape(k, 2), beta=x[2 * k],
                         scale=x[2 * k + 1], d0=d0)

    x0 = np.concatenate([st.track.ravel(), [st.beta, st.scale], st.d0[list(free)]])
    grad = np.concatenate([ne.grad_p, ne.grad_g])
    eps = 1e-5
    for i in [0, 1, 2, 5, 2 * k - 1, 2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3, 2 * k + 4]:
        e = np.zeros_like(x0)
        e[i] = eps
        assert grad[i] == pytest.approx((at(x0 + e) - at(x0 - e)) / (2 * eps), rel=1e-5,
                                        abs=1e-4)
    # a Gauss-Newton step lowers the objective (its Hessian is the one solved)
    step = solve(ne)
    x1 = x0 + np.concatenate([step.dp.ravel(), step.dg])
    assert at(x1) < at(x0)


def test_range_scale_column_is_the_gradient_of_the_objective():
    """The range scale's row of the normal equations: gradient by finite differences, and a
    Gauss-Newton step lowers the objective."""
    sim = simulate_dive("abe58", rng=0, n_cycles=25)
    dive = build_dive(sim.survey)
    k, nb = dive.n_epochs, len(dive.beacon_ids)
    rng = np.random.default_rng(1)
    st = State(dive.dr + rng.normal(0, 5, (k, 2)), 0.02, 1.01,
               dive.beacon_xyz[:, 2] + rng.normal(0, 3, nb), np.array([False, True, False, True]),
               4.0, np.full(nb, 8.0), np.full((nb, 3), 1 / 3), range_scale=1.001)
    a, b = rng.random(dive.n) / 16, rng.random(dive.n) / 64
    pri = Priors(0.1, 100.0, 0.1, 0.05, 1000.0)
    free = (0, 3)
    ne = normal_equations(dive, st, a, b, pri, free, True)

    def at(x):
        d0 = st.d0.copy()
        d0[list(free)] = x[2 * k + 2:2 * k + 4]
        return objective(dive, st, a, b, pri, track=x[:2 * k].reshape(k, 2), beta=x[2 * k],
                         scale=x[2 * k + 1], d0=d0, range_scale=x[-1])

    x0 = np.concatenate([st.track.ravel(), [st.beta, st.scale], st.d0[list(free)], [1.001]])
    grad = np.concatenate([ne.grad_p, ne.grad_g])
    for i, eps in ((0, 1e-5), (2 * k + 2, 1e-5), (x0.size - 1, 1e-8)):
        e = np.zeros_like(x0)
        e[i] = eps
        assert grad[i] == pytest.approx((at(x0 + e) - at(x0 - e)) / (2 * eps), rel=1e-4,
                                        abs=1e-3)
    step = solve(ne)
    assert at(x0 + np.concatenate([step.dp.ravel(), step.dg])) < at(x0)
    # its Gauss-Newton blocks: J^T W J with dF/dk = F / k
    pred = predictions(dive, st)
    jd, jm = pred.direct / 1.001, pred.multipath / 1.001
    want_b = np.zeros((k, 2))
    for ax in range(2):
        want_b[:, ax] = np.bincount(dive.epoch, weights=a * pred.grad_direct[:, ax] * jd
                                    + b * pred.grad_multipath[:, ax] * jm, minlength=k)
    np.testing.assert_allclose(ne.B[:, -1], want_b.ravel(), rtol=1e-9)
    assert ne.C[-1, -1] == pytest.approx(np.sum(a * jd ** 2 + b * jm ** 2) + 1e4, rel=1e-9)
    m = dive.beacon == 3
    assert ne.C[-1, 3] == pytest.approx(np.sum(b[m] * jm[m] * pred.d_multipath_d0[m]), rel=1e-9)


def _dense(diag, B, C):
    k, g = diag.shape[0], C.shape[0]
    H = np.zeros((2 * k + g, 2 * k + g))
    for i in range(k):
        H[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[diag[i, 0], diag[i, 1]], [diag[i, 1], diag[i, 2]]]
    H[:2 * k, 2 * k:], H[2 * k:, :2 * k], H[2 * k:, 2 * k:] = B, B.T, C
    return H


@pytest.mark.parametrize("free_k", [False, True])
def test_missing_information_is_louis_identity_for_every_reply(free_k):
    """Complete-data information less the missing one = the observed information (Louis);
    with the range scale estimated too."""
    sim = simulate_dive("random", rng=4, n_cycles=12)
    dive = build_dive(sim.survey)
    k, nb = dive.n_epochs, len(dive.beacon_ids)
    rng = np.random.default_rng(2)
    st = State(dive.dr + rng.normal(0, 3, (k, 2)), 0.0, 1.0,
               dive.d0_min + rng.uniform(1, 20, nb), np.zeros(nb, bool), 40.0,
               np.full(nb, 60.0), np.tile([0.5, 0.3, 0.2], (nb, 1)),  # plane low: classes overlap
               range_scale=1.002 if free_k else 1.0)
    pred = predictions(dive, st)
    lw = np.log(st.weights[dive.beacon])
    lol = dive.log_ol
    s_dp, s_mp = st.sigma_dp, st.sigma_mp[dive.beacon]

    def nll(f_dp, f_mp):  # minus the log mixture density of every reply at predictions f
        comp = np.stack([lw[:, 0] - 0.5 * ((dive.z - f_dp) / s_dp) ** 2 - np.log(s_dp),
                         lw[:, 1] - 0.5 * ((dive.z - f_mp) / s_mp) ** 2 - np.log(s_mp),
                         lw[:, 2] + lol])
        top = comp.max(axis=0)
        return -(top + np.log(np.exp(comp - top).sum(axis=0)))

    comp = np.stack([lw[:, 0] - 0.5 * ((dive.z - pred.direct) / s_dp) ** 2 - np.log(s_dp),
                     lw[:, 1] - 0.5 * ((dive.z - pred.multipath) / s_mp) ** 2 - np.log(s_mp),
                     lw[:, 2] + lol])
    resp = np.exp(comp - comp.max(axis=0))
    resp = (resp / resp.sum(axis=0)).T
    assert (resp[:, 0] * resp[:, 1]).max() > 0.2  # replies between direct path and multipath
    assert (resp[:, 1] * resp[:, 2]).max() > 0.05  # and between multipath and outlier
    free = tuple(range(nb))
    eps = 1e-2  # m: the densities are smooth on the scale of sigma (40-60 m)
    f = np.stack([pred.direct, pred.multipath])
    hess = np.zeros((dive.n, 2, 2))  # numerical Hessian of nll in (f_dp, f_mp), every reply
    for a in range(2):
        for b in range(2):
            ea, eb = np.eye(2)[a][:, None] * eps, np.eye(2)[b][:, None] * eps
            hess[:, a, b] = (nll(*(f + ea + eb)) - nll(*(f + ea - eb)) - nll(*(f - ea + eb))
                             + nll(*(f - ea - eb))) / (4 * eps * eps)
    complete = np.zeros((dive.n, 2, 2))
    complete[:, 0, 0], complete[:, 1, 1] = resp[:, 0] / s_dp ** 2, resp[:, 1] / s_mp ** 2
    jac = np.zeros((dive.n, 2, 2 * k + 2 + nb + free_k))  # d(f_dp, f_mp) / d(track, ..., k)
    if free_k:
        jac[:, 0, -1], jac[:, 1, -1] = pred.direct / 1.002, pred.multipath / 1.002
    for i in range(dive.n):
        e, j = dive.epoch[i], dive.beacon[i]
        jac[i, 0, 2 * e:2 * e + 2] = pred.grad_direct[i]
        jac[i, 1, 2 * e:2 * e + 2] = pred.grad_multipath[i]
        jac[i, 1, 2 * k + 2 + j] = pred.d_multipath_d0[i]
    want = np.einsum("iap,iab,ibq->pq", jac, complete - hess, jac)
    got = _dense(*missing_information(dive, st, resp, free, free_k))
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5 * np.abs(want).max())
    hard = (resp == resp.max(axis=1, keepdims=True)).astype(float)
    assert not np.any(_dense(*missing_information(dive, st, hard, free, free_k)))


@pytest.mark.parametrize(("k", "g", "m"), [(5, 0, 2), (40, 3, 4)])
def test_solve_columns_matches_the_dense_system(k, g, m):
    ne, H = _random_system(k, g, seed=10 * k + g)
    rhs = np.random.default_rng(k).normal(size=(2 * k + g, m))
    x, y = solve_columns(ne, solve(ne), rhs[:2 * k], rhs[2 * k:])
    np.testing.assert_allclose(np.vstack([x, y]), np.linalg.solve(H, rhs), atol=1e-9)
