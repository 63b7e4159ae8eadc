"""The per-ping kernel follows navigate's vectorised model (defined once, there)."""

import math

import numpy as np
import pytest

from bayes_mpem.lbl.navigate import model
from bayes_mpem.lbl.navigate.online import kernel


@pytest.mark.parametrize("double", [False, True])
def test_ranges_match_predict_ranges(double):
    gen = np.random.default_rng(0)
    for _ in range(200):
        x, y = gen.uniform(-3000, 3000, 2)
        bx, by = gen.uniform(-3000, 3000, 2)
        bz = gen.uniform(50, 4000)
        depth = gen.uniform(0, bz)
        d0 = gen.uniform(bz - depth, bz + 50)
        got = kernel.ranges(x, y, depth, bx, by, bz, d0, double)
        ref = model.predict_ranges(x, y, depth, (bx, by, bz), d0,
                                   "double" if double else "triangle")
        want = (ref.direct, ref.multipath, *ref.grad_direct, *ref.grad_multipath,
                ref.d_multipath_d0)
        np.testing.assert_allclose(got, np.array(want, float), rtol=1e-12, atol=1e-12)


def test_class_probabilities_match_class_log_joint():
    gen = np.random.default_rng(1)
    for i in range(300):
        direct = gen.uniform(100, 5000)
        mp = direct + gen.uniform(0, 2000)
        z = gen.choice([direct, mp, gen.uniform(1, 8000)]) + gen.normal(0, 10)
        s_dp, s_mp = gen.uniform(0.5, 20, 2)
        w = gen.dirichlet([1, 1, 1])
        if i % 5 == 0:
            w[1] = 0.0  # the multipath class switched off
        lw = [math.log(v) if v > 0 else -math.inf for v in w]
        log_ol = -math.log(gen.uniform(1000, 9000))
        got = kernel.class_probabilities(z, direct, mp, s_dp, s_mp, log_ol, *lw)
        resp, lse = model.class_log_joint(z, direct, mp, s_dp, s_mp, log_ol, np.array(lw))
        np.testing.assert_allclose(got[:3], resp, rtol=1e-10, atol=1e-300)
        assert got[3] == pytest.approx(float(lse), rel=1e-12)
        assert kernel.log_weight(w[1]) == lw[1]


def test_dr_step_matches_model():
    gen = np.random.default_rng(2)
    for _ in range(100):
        delta = gen.normal(0, 20, 2)
        beta, scale = gen.normal(0, 0.05), gen.uniform(0.9, 1.1)
        p, d_beta, d_scale = model.dr_step([0.0, 0.0], delta, beta, scale)
        got = kernel.dr_step(*delta, beta, scale)
        np.testing.assert_allclose(got, [*p, *d_beta, *d_scale], rtol=1e-12, atol=1e-12)
