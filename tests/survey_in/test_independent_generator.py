"""Sentinels of the independent GNSS-A generator study (``benchmarks/gnssa_independent.py``).

The generator was written without the package's model or simulator; these checks keep it
honest (its rays against a straight line and a quadrature, its frame against ``locate`` on
noise-free campaigns) and keep one small case of the study (``docs/gnssa.md``, "On an
independently written generator").
"""

import importlib.util
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "gnssa_independent.py"


@pytest.fixture(scope="module")
def gen():
    spec = importlib.util.spec_from_file_location("gnssa_independent", PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # the dataclasses look their module up
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.modules.pop(spec.name, None)


def test_rays_in_constant_water_are_straight(gen):
    cfg = gen.Config(profile="constant", varying=False, gradients=False)
    ocean = gen.Ocean(cfg, np.random.default_rng(0), [0.0, 0.0, 0.0])
    radius = gen.gaussian_radius(cfg.lat)
    src = np.array([[3000.0, 100.0, -5.0], [10.0, -2000.0, -4.0], [0.0, 0.0, -3.0]])
    dst = np.array([[500.0, -700.0, -3010.0], [0.0, 0.0, -3000.0], [0.0, 0.0, -2990.0]])
    t = gen.leg_times(ocean, radius, src, dst, np.zeros(3))
    np.testing.assert_allclose(t, np.linalg.norm(dst - src, axis=1) / 1500.0, rtol=0, atol=1e-11)


def test_spherical_eigenray_matches_the_quadrature(gen):
    from scipy.integrate import quad
    from scipy.optimize import brentq

    cfg = gen.Config(varying=False, gradients=False)
    ocean = gen.Ocean(cfg, np.random.default_rng(0), [0.0, 0.0, 0.0])
    radius = gen.gaussian_radius(cfg.lat)
    centre = np.array([0.0, 0.0, -radius])
    v = np.array([4000.0, 0.0, 0.0]) - centre
    src = (centre + v / np.linalg.norm(v) * (radius - 5.0))[None, :]
    dst = np.array([[0.0, 0.0, -3000.0]])
    layered = gen.leg_times(ocean, radius, src, dst, np.zeros(1))[0]
    vs, vd = src[0] - centre, dst[0] - centre
    phi = np.arctan2(np.linalg.norm(np.cross(vs, vd)), vs @ vd)
    rs, rd = np.linalg.norm(vs), np.linalg.norm(vd)

    def c(r):
        return float(ocean.c0(radius - r))

    def angle(p):  # Bouguer: r sin(i) / c = p along a ray in spherical shells
        return quad(lambda r: p * c(r) / (r * np.sqrt(r * r - (p * c(r)) ** 2)), rd, rs,
                    limit=400, points=[radius - 50.0])[0] - phi

    p = brentq(angle, 0.3 * radius / 1550.0, 0.99 * (radius - 3000.0) / 1549.0, xtol=1e-12,
               rtol=1e-15)
    exact = quad(lambda r: r / (c(r) * np.sqrt(r * r - (p * c(r)) ** 2)), rd, rs, limit=400,
                 points=[radius - 50.0], epsabs=1e-13)[0]
    assert abs(layered - exact) < 0.05e-6  # measured 0.0035 us


def test_noise_free_campaign_is_located_to_a_millimetre(gen, tmp_path):
    """Straight rays (constant water), no field change, no noise: the frame is the reader's."""
    cfg = gen.Config(scenario="B", hours=1.5, profile="constant", varying=False,
                     gradients=False, noise=False, outliers=False)
    r = gen.run(0, cfg, tmp_path)
    assert np.abs(r["tp_err"]).max() < 1e-3  # measured 0.02 mm
    truth = json.loads((tmp_path / "campaign" / "truth.json").read_text())
    assert truth["labels"] == {"true": r["n"], "multipath": 0, "spurious": 0}


def test_refracted_rays_agree_with_the_flat_model(gen, tmp_path):
    """The Munk profile, flat layers on both sides, one speed: refraction and lever arm right."""
    from bayes_mpem.io.formats import read_survey
    from bayes_mpem.survey_in.array_survey import locate_array_survey

    cfg = replace(gen.Config(scenario="A", hours=1.0, earth="flat"), varying=False,
                  gradients=False, noise=False, outliers=False)
    camp = gen.campaign(0, cfg)
    raw = read_survey(gen.write_campaign(camp, tmp_path), "garpos")
    res = locate_array_survey(raw, speed_intervals=0, earth="flat")
    err = gen.compare(res.summary, camp["truth"])["tp_err"]
    assert np.abs(err).max() < 1e-3  # measured 0.4 mm (2 h)


def test_small_campaign_centre_within_the_study_s_tolerance(gen, tmp_path):
    """One small noisy campaign with outliers (star, in turn, no time change): the centre."""
    cfg = gen.Config(scenario="B", hours=3.0, varying=False)
    r = gen.run(0, cfg, tmp_path)
    z = r["centre_err"] / r["centre_sd"]
    # measured on seeds 0-3 of this setting: |z| up to 2.02 (seed 0), horizontal 7.6 cm (seed
    # 0) with sds near 3 cm, vertical up to 3.3 cm; the 6 h study: horizontal up to 5 cm
    assert np.all(np.abs(z) < 3.5), z
    assert np.hypot(*r["centre_err"][:2]) < 0.10 and abs(r["centre_err"][2]) < 0.10
