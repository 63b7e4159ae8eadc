"""The joint model of the diagnosis: its Jacobian and the parameters of its terms."""

import numpy as np
import pytest

from bayes_mpem.lbl.diagnosis.model import predict, ranges
from bayes_mpem.lbl.diagnosis.params import (
    Params,
    beacons_with,
    get_vector,
    mean_names,
    set_vector,
    without,
)
from bayes_mpem.lbl.simulation.effects import split_term, term, term_order
from bayes_mpem.lbl.simulation.simulate import simulate_survey
from bayes_mpem.lbl.survey.survey import fittable_beacons

TERMS = ("range_bias", "sound_speed", "plane_drift", "second_reflector", "nav_drift",
         "beacon_bias:2", "beacon_position:3")


@pytest.fixture(scope="module")
def data():
    sim = simulate_survey("abe58", rng=0, n_cycles=120)
    return ranges(sim.survey, fittable_beacons(sim.survey, 30)[0])


def _params(d):
    gen = np.random.default_rng(1)
    return Params(plane=gen.uniform(-5, 5, d.nb), sigma=np.full((d.nb, 3), 4.0),
                  weights=np.tile([0.6, 0.25, 0.05, 0.1], (d.nb, 1)), bias=1.5, scale=0.003,
                  drift=4.0, plane2=600.0, nav=np.array([7.0, -4.0]),
                  bbias=gen.normal(0, 3, d.nb), bpos=gen.normal(0, 10, (d.nb, 3)))


@pytest.mark.parametrize("path", ["triangle", "double"])
def test_jacobian_matches_finite_differences(data, path):
    p = _params(data)
    names = mean_names(TERMS, data.ids)
    assert ("bbias", 1) in names and ("bpos_x", 2) in names and ("bpos_y", 2) in names
    _, jac = predict(data, p, TERMS, path, names)
    v = get_vector(p, names)
    for i, name in enumerate(names):
        h = 1e-4 * max(1.0, abs(v[i]))
        up, dn = v.copy(), v.copy()
        up[i] += h
        dn[i] -= h
        mu_up = predict(data, set_vector(p, names, up), TERMS, path)
        mu_dn = predict(data, set_vector(p, names, dn), TERMS, path)
        for c in ("dp", "mp", "mp2"):
            fd = (mu_up[c] - mu_dn[c]) / (2 * h)
            np.testing.assert_allclose(jac[c][:, i], fd, rtol=1e-5, atol=1e-6,
                                       err_msg=f"{name} {c}")


def test_terms_and_their_parameters(data):
    assert term("beacon_bias", "2") == "beacon_bias:2"
    assert split_term("beacon_position:3") == ("beacon_position", "3")
    assert sorted(["beacon_bias:2", "nav_drift", "range_bias"], key=term_order) == [
        "range_bias", "nav_drift", "beacon_bias:2"]
    assert beacons_with(TERMS, "beacon_position", data.ids) == [2]
    p = _params(data)
    q = without(p, "beacon_bias:2", data.ids)
    assert q.bbias[1] == 0.0 and q.bbias[0] == p.bbias[0]
    q = without(p, "plane_drift", data.ids)
    np.testing.assert_allclose(q.plane, p.plane + 2.0)  # the mean plane is kept
    # a term switched off leaves the predictions as if its parameters were 0
    off = predict(data, p, ("range_bias",), "triangle")
    zero = predict(data, without(p, "beacon_position:3", data.ids), ("range_bias",), "triangle")
    np.testing.assert_array_equal(off["dp"], zero["dp"])
