import numpy as np
import pytest
from scipy import optimize

from bayes_mpem.lbl.model import geometry


def _image_free_triangle(h, dz, d0):
    """Triangle path found by minimising over the reflection point (no image method)."""
    # beacon at (0, 0) height 0; vehicle at (h, dz) height above beacon; plane at height d0.
    def reflected(s):
        return np.hypot(s, d0) + np.hypot(h - s, d0 - dz)

    best = optimize.minimize_scalar(reflected, bounds=(0.0, h), method="bounded",
                                    options={"xatol": 1e-10})
    return 0.5 * (np.hypot(h, dz) + best.fun), best.fun


@pytest.mark.parametrize(("h", "dz", "d0"), [(3000.0, 0.0, 2472.0), (700.0, 45.0, 2404.0),
                                             (50.0, 300.0, 1000.0), (2500.0, -20.0, 2391.0)])
def test_multipath_matches_specular_reflection(h, dz, d0):
    tri, refl = _image_free_triangle(h, dz, d0)
    assert geometry.multipath_range(h, dz, d0) == pytest.approx(tri, abs=1e-6)
    assert geometry.multipath_range(h, dz, d0, "double") == pytest.approx(refl, abs=1e-6)


def test_notes_beacon4_check():
    # NOTES.md: beacon 4, h ~ 3 km: DP ~3 km, triangle MP ~4.4 km, double ~5.8 km
    assert geometry.direct_path(3000.0, 0.0) == pytest.approx(3000.0)
    assert geometry.multipath_range(3000.0, 0.0, 2472.0) == pytest.approx(4391.5, abs=0.1)
    assert geometry.multipath_range(3000.0, 0.0, 2472.0, "double") == pytest.approx(5783.0,
                                                                                   abs=0.1)


@pytest.mark.parametrize("path", ["triangle", "double"])
def test_inversion_round_trip(path):
    rng = np.random.default_rng(0)
    h = rng.uniform(0, 5000, 1000)
    dz = rng.uniform(-100, 500, 1000)
    d0 = rng.uniform(600, 4000, 1000)
    z = geometry.multipath_range(h, dz, d0, path)
    np.testing.assert_allclose(geometry.invert_plane_height(z, h, dz, path), d0, rtol=1e-10)


def test_inversion_undefined_below_direct_path():
    h, dz = np.array([1000.0, 1000.0]), np.array([10.0, 10.0])
    z = geometry.direct_path(h, dz) * np.array([0.5, 0.99])
    out = geometry.invert_plane_height(z, h, dz)
    assert np.all(np.isnan(out))


@pytest.mark.parametrize("path", ["triangle", "double"])
def test_derivative_matches_finite_difference(path):
    h, dz, d0 = np.array([10.0, 800.0, 4000.0]), np.array([30.0, -5.0, 200.0]), 2400.0
    eps = 1e-4
    fd = (geometry.multipath_range(h, dz, d0 + eps, path)
          - geometry.multipath_range(h, dz, d0 - eps, path)) / (2 * eps)
    np.testing.assert_allclose(geometry.multipath_derivative(h, dz, d0, path), fd, rtol=1e-6)


def test_broadcasting_over_walkers():
    h, dz = np.linspace(100, 3000, 7), np.full(7, 40.0)
    d0 = np.array([[2300.0], [2400.0]])
    out = geometry.multipath_range(h, dz, d0)
    assert out.shape == (2, 7)
    np.testing.assert_allclose(out[1], geometry.multipath_range(h, dz, 2400.0))


def test_unknown_path_is_rejected():
    with pytest.raises(ValueError, match="expected one of .*'triangle'.*got 'single'"):
        geometry.multipath_range(1.0, 1.0, 1.0, "single")


def test_horizontal_slopes_match_finite_differences():
    rng = np.random.default_rng(0)
    h, dz, d0 = rng.uniform(10, 3000, 20), rng.uniform(-50, 300, 20), rng.uniform(400, 2500, 20)
    eps = 1e-4
    for path in ("triangle", "double"):
        sd, sm = geometry.horizontal_slopes(h, dz, d0, path)
        num_d = (geometry.direct_path(h + eps, dz) - geometry.direct_path(h - eps, dz)) / (2 * eps)
        num_m = (geometry.multipath_range(h + eps, dz, d0, path)
                 - geometry.multipath_range(h - eps, dz, d0, path)) / (2 * eps)
        # dR/dx = (x - x_b) * slope and dh/dx = (x - x_b) / h, so dR/dh = h * slope
        np.testing.assert_allclose(h * sd, num_d, rtol=1e-6)
        np.testing.assert_allclose(h * sm, num_m, rtol=1e-6)


def test_per_range_paths_match_one_path_each():
    h, dz, d0 = np.array([500.0, 1500.0, 2500.0]), np.array([10.0, 40.0, 0.0]), 2400.0
    paths = np.array(["triangle", "double", "triangle"])
    mixed = geometry.multipath_range(h, dz, d0, paths)
    for i, p in enumerate(paths):
        assert mixed[i] == pytest.approx(geometry.multipath_range(h[i], dz[i], d0, p))
        assert geometry.multipath_derivative(h, dz, d0, paths)[i] == pytest.approx(
            geometry.multipath_derivative(h[i], dz[i], d0, p))
    np.testing.assert_array_equal(geometry.multipath_range(h, dz, d0, paths == "double"), mixed)
    with pytest.raises(ValueError, match="path"):
        geometry.multipath_range(h, dz, d0, np.array(["triangle", "single", "double"]))
