"""The sparse solve, the selected inversion and the normal equations of the objective."""

import numpy as np
import pytest

from bayes_mpem.lbl.navigate.dive import build_dive
from bayes_mpem.lbl.navigate.normal import (
    Normal,
    band,
    global_covariance,
    marginal_covariances,
    solve,
)
from bayes_mpem.lbl.navigate.objective import Priors, State, normal_equations, objective
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
