"""The safeguarded Gauss-Newton step (bayes_mpem.mixture.gauss_newton)."""

import numpy as np
import pytest

from bayes_mpem.mixture.gauss_newton import safeguarded_step


def _quadratic(seed, n=40, m=3):
    gen = np.random.default_rng(seed)
    a = gen.normal(size=(n, m))
    y = gen.normal(size=n)
    w = gen.uniform(0.1, 2.0, size=n)

    def objective(x):
        r = y - a @ x
        return float(np.sum(w * r * r)), r

    return a, y, w, objective


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_on_a_quadratic(seed):
    """A Gauss-Newton step on a weighted linear least-squares problem lands on its minimum."""
    a, y, w, objective = _quadratic(seed)
    x0 = np.zeros(a.shape[1])
    f0, r0 = objective(x0)
    aw = a * w[:, None]
    step = np.linalg.solve(aw.T @ a, aw.T @ r0)  # the Gauss-Newton step
    out = safeguarded_step(objective, x0, step, f0)
    best = np.linalg.lstsq(a * np.sqrt(w)[:, None], y * np.sqrt(w), rcond=None)[0]
    np.testing.assert_allclose(out.x, best, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(out.step, step)  # taken whole, no halving


@pytest.mark.parametrize("seed", range(5))
def test_never_increases_the_objective(seed):
    """Whatever the proposed step, the accepted point is no worse than the start."""
    gen = np.random.default_rng(seed)
    _, _, _, objective = _quadratic(seed)
    x0 = gen.normal(size=3)
    f0 = objective(x0)[0]
    for _ in range(20):  # arbitrary, mostly bad, steps
        out = safeguarded_step(objective, x0, gen.normal(scale=10.0, size=3), f0)
        assert out is None or out.value <= f0
        if out is not None:
            assert out.value == objective(out.x)[0]


def test_respects_bounds_scalar_and_vector():
    """Candidates are clipped into the bounds (scalar as a float, vector elementwise)."""
    def f(x):
        return float(np.sum((np.asarray(x) - 3.0) ** 2)), None

    out = safeguarded_step(f, 0.0, 10.0, f(0.0)[0], bounds=(-1.0, 2.0))
    assert out.x == 2.0 and isinstance(out.x, float)
    out = safeguarded_step(f, np.zeros(2), np.array([10.0, -10.0]), f(np.zeros(2))[0],
                           bounds=(-1.0, 2.0))
    assert np.all(out.x >= -1.0) and np.all(out.x <= 2.0)
    assert out.value <= f(np.zeros(2))[0]


def test_infeasible_or_uphill_gives_none():
    """No acceptable candidate gives None; infeasible ones are halved away."""
    assert safeguarded_step(lambda x: None, 0.0, 1.0, 0.0) is None
    assert safeguarded_step(lambda x: (x * x + 1.0, None), 0.0, 1.0, 0.0, max_halvings=5) is None
    # infeasible beyond 0.3: halved until inside
    out = safeguarded_step(lambda x: None if x > 0.3 else ((x - 1.0) ** 2, None), 0.0, 1.0, 1.0)
    assert out.x == 0.25 and out.step == 0.25
