"""The Earth's curvature in the array model: the profile's layers follow the sphere."""

import numpy as np
import pytest

from bayes_mpem.io.geodesy import earth_radius
from bayes_mpem.survey_in.array import ArrayTravelTimes, from_sphere, to_sphere
from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa


def test_heights_above_the_sphere_are_pymap3d_ellipsoidal_heights():
    pm = pytest.importorskip("pymap3d")
    lat0, lon0, h0 = 38.0, 143.0, 0.0
    gen = np.random.default_rng(0)
    e, n = gen.uniform(-3000.0, 3000.0, (2, 50))
    u = gen.uniform(-3000.0, 30.0, 50)
    _, _, h = pm.enu2geodetic(e, n, u, lat0, lon0, h0)
    hs = to_sphere(e, n, u, earth_radius(lat0))[2]
    # the sphere's height is the ellipsoid's to 1.4 mm within 4.2 km (the flat up is 1.4 m off)
    assert np.abs(hs - h).max() < 2e-3
    assert np.abs(u - h).max() > 0.5  # the flat frame's up is not (1.4 m at 4 km)
    back = from_sphere(*to_sphere(e, n, u, 6371e3), 6371e3)
    np.testing.assert_allclose(back, (e, n, u), atol=1e-8)


def test_the_jacobian_is_cartesian_with_curvature():
    sim = simulate_gnssa(n_transponders=3, hours=0.2, rng=31)
    shots = array_shots(sim.raw())
    idx = shots["transponder"].map({"M01": 0, "M02": 1, "M03": 2}).to_numpy()
    from bayes_mpem.acoustics.profile import SoundSpeedProfile

    prof = SoundSpeedProfile(sim.header["ss_prof"]["depth"], sim.header["ss_prof"]["sound_speed"])
    model = ArrayTravelTimes(shots, idx, 3, np.ones((len(shots), 1)), profile=prof,
                             earth_radius=6371e3)
    theta = np.r_[sim.truth["transponders"].to_numpy().ravel(), 1.0]
    J = model.jac(theta)
    for j in range(9):
        up, dn = theta.copy(), theta.copy()
        up[j] += 1e-3
        dn[j] -= 1e-3
        np.testing.assert_allclose(J[:, j], (model.predict(up) - model.predict(dn)) / 2e-3,
                                   rtol=1e-4, atol=1e-10)


def test_a_curved_ocean_is_located_with_curvature():
    """Located with the model it was simulated with, the same errors, curved or flat."""
    truth, err = None, {}
    for earth in ("sphere", "flat"):
        sim = simulate_gnssa(hours=1.0, rng=32, depth=3000.0, sigma=1e-6, p_spurious=0.0,
                             speed_amplitude=0.0, earth=earth)
        truth = sim.truth["transponders"].to_numpy()
        for fit in ("sphere", "flat"):
            res = locate_array_survey(sim.raw(), speed_intervals=0, earth=fit)
            err[earth, fit] = res.fits["array"].enu - truth
    np.testing.assert_allclose(err["sphere", "sphere"], err["flat", "flat"], atol=2e-4)
    # the wrong model (flat layers): 1.5 mm or more too deep at 3 km, the transponders alike
    wrong = err["sphere", "flat"][:, 2] - err["sphere", "sphere"][:, 2]
    assert np.all(wrong < -1.5e-3), wrong
    res = locate_array_survey(simulate_gnssa(hours=0.3, rng=33).raw(), speed_intervals=0)
    assert "sphere of radius" in res.summary["geometry"]["earth"]
    assert res.summary["geometry"]["earth_radius_m"] == pytest.approx(earth_radius(38.0))
