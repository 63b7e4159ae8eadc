"""The noise scales' uncertainty in the ellipses (issue 25, item 4): the law of total
variance to first order (the track's sensitivity to log sigma, MacKay's variance of log
sigma), checked against a dense computation with numerical cross-derivatives."""

import dataclasses
import warnings

import numpy as np
import pytest

from bayes_mpem.exceptions import NavigationWarning
from bayes_mpem.lbl.navigate import driver, navigate, simulate_dive
from bayes_mpem.lbl.navigate.normal import (
    band,
    cross_covariances,
    global_covariance,
    marginal_covariances,
    solve,
)
from bayes_mpem.lbl.navigate.objective import normal_equations, predictions


@pytest.fixture(scope="module")
def nav():
    sim = simulate_dive("abe58", rng=3, n_cycles=120)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        return navigate(sim.survey, rng=0, path="triangle")


def _dense(ne):
    k, g = ne.diag.shape[0], ne.C.shape[0]
    H = np.zeros((2 * k + g, 2 * k + g))
    ab = band(ne.diag, ne.lam)
    for d in range(3):
        for j in range(2 * k - d):
            H[j + d, j] = H[j, j + d] = ab[d, j]
    H[:2 * k, 2 * k:], H[2 * k:, :2 * k], H[2 * k:, 2 * k:] = ne.B, ne.B.T, ne.C
    return H


def test_matches_the_dense_computation(nav):
    """D = d theta / d log sigma from numerical cross-derivatives and the dense Hessian,
    MacKay's var(log sigma) = 1 / (2 (n - gamma)) from dense leverages."""
    dive, st, resp = nav.dive, nav.state, nav.resp
    settings = driver._settings(dive, nav.options, {}, None)
    mp = [j for j in range(len(dive.beacon_ids)) if nav.beacons[dive.beacon_ids[j]]["mp"]]
    assert mp  # the dive has multipath: sigma_DP and the sigma_MPs are all propagated
    settings = dataclasses.replace(settings, mp_beacons=np.isin(np.arange(4), mp),
                                   free_d0=tuple(mp))
    a = resp[:, 0] / st.sigma_dp ** 2
    b = resp[:, 1] / st.sigma_mp[dive.beacon] ** 2
    pri, free = settings.priors, settings.free_d0
    ne = normal_equations(dive, st, a, b, pri, free)
    step = solve(ne)
    cov0, g0, x0 = marginal_covariances(ne, step), global_covariance(step), cross_covariances(step)
    cov, gcov, cross, sd_log = driver.propagate_scales(dive, st, resp, settings, ne, step,
                                                       cov0, g0, x0)
    names = list(sd_log)
    assert names[0] == "sigma_dp" and len(names) == 1 + len(mp)

    H = _dense(ne)
    P = np.linalg.inv(H)
    k, g = dive.n_epochs, gcov.shape[0]
    # every reply's dense Jacobian (track and globals) of its direct and multipath ranges
    pred = predictions(dive, st)
    Jd = np.zeros((dive.n, 2 * k + g))
    Jm = np.zeros((dive.n, 2 * k + g))
    rows = np.arange(dive.n)
    for ax in range(2):
        Jd[rows, 2 * dive.epoch + ax] = pred.grad_direct[:, ax]
        Jm[rows, 2 * dive.epoch + ax] = pred.grad_multipath[:, ax]
    for col, j in enumerate(free, start=2):
        m = dive.beacon == j
        Jm[m, 2 * k + col] = pred.d_multipath_d0[m]
    lev_d = np.einsum("ia,ab,ib->i", Jd, P, Jd) / st.sigma_dp ** 2
    lev_m = np.einsum("ia,ab,ib->i", Jm, P, Jm) / st.sigma_mp[dive.beacon] ** 2
    eps, cols, var = 1e-5, [], []
    for name in names:
        if name == "sigma_dp":
            sel = np.ones(dive.n, bool)
            n, gamma = resp[:, 0].sum(), np.sum(resp[:, 0] * lev_d)
        else:
            sel = dive.beacon == dive.beacon_ids.index(name.split(":")[1])
            n, gamma = resp[sel, 1].sum(), np.sum((resp[:, 1] * lev_m)[sel])
        var.append(0.5 / (n - gamma))
        grads = []
        for sgn in (1.0, -1.0):
            f = np.exp(-2.0 * sgn * eps)  # a weight 1 / sigma^2 at sigma e^(+-eps)
            aa = np.where(sel, a * f, a) if name == "sigma_dp" else a
            bb = b if name == "sigma_dp" else np.where(sel, b * f, b)
            e = normal_equations(dive, st, aa, bb, pri, free)
            grads.append(np.concatenate([e.grad_p, e.grad_g]))
        cols.append((grads[0] - grads[1]) / (2 * eps))
    D = np.linalg.solve(H, np.column_stack(cols))
    full = P + D @ np.diag(var) @ D.T
    for i in (0, k // 2, k - 1):
        np.testing.assert_allclose(cov[i], full[2 * i:2 * i + 2, 2 * i:2 * i + 2], rtol=1e-6)
    np.testing.assert_allclose(gcov, full[2 * k:, 2 * k:], rtol=1e-6, atol=1e-14)
    np.testing.assert_allclose(cross.reshape(2 * k, g), full[:2 * k, 2 * k:], rtol=1e-5,
                               atol=1e-12)
    np.testing.assert_allclose(list(sd_log.values()), np.sqrt(var), rtol=1e-6)
    # the scales only add uncertainty, and not nothing
    grow = np.linalg.det(cov) / np.linalg.det(cov0)
    assert np.all(grow >= 1.0 - 1e-12) and grow.max() > 1.0 + 1e-6


def test_summary_reports_it_and_fixed_scales_are_not_propagated(nav):
    s = nav.summary()["scale_uncertainty"]
    assert set(s["sd_log_sigma"]) >= {"sigma_dp"}
    # sd of log sigma_DP about 1 / sqrt(2 n) (n the direct-path replies; a little more: the
    # track's degrees of freedom), and the summary's interval of sigma_DP from it
    n = float(nav.resp[:, 0].sum())
    assert 1.0 <= s["sd_log_sigma"]["sigma_dp"] * np.sqrt(2 * n) <= 1.5
    sdp = nav.summary()["sigma_dp"]
    assert sdp["sd"] == pytest.approx(sdp["estimate"] * s["sd_log_sigma"]["sigma_dp"])
    assert 0.0 <= s["ellipse_widening"]["median"] <= s["ellipse_widening"]["max"] < 0.05
    settings = driver._settings(nav.dive, {**nav.options, "sigma_dp": 0.2}, {}, None)
    names = [n for _, _, n in driver._free_scales(nav.dive, nav.state, nav.resp, settings)]
    assert "sigma_dp" not in names
