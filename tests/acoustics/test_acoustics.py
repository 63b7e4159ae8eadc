"""Sound-speed profiles and refracted eigenrays, against independent references.

References: the straight line and the image method (homogeneous medium); the
Hamiltonian ray equations integrated with ``solve_ivp`` (DOP853, rtol = atol =
1e-12, restarted at every knot so that ``dc/dz`` is smooth in each piece); and a
Snell sum over 0.1 m and 0.05 m piecewise-constant layers (midpoint speed),
Richardson-extrapolated. Tolerances asserted: straight line 1e-6 m; ODE and
Snell sum 1e-5 m in horizontal distance and 1e-9 s in time.
"""

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

from bayes_mpem.acoustics.eigenray import direct_ray, shoot, surface_bounce_ray
from bayes_mpem.acoustics.profile import WOA09_ENV, SoundSpeedProfile
from bayes_mpem.exceptions import InputError
from bayes_mpem.lbl.model import geometry

DATA = Path(__file__).resolve().parents[2] / "data"
WOA09 = DATA / "woa09"
CC03 = (-4.8816, -132.68895)

# constant-gradient layers with gradients of both signs, a zero-gradient layer
# and a speed maximum inside the water column
LAYERED = SoundSpeedProfile([0.0, 60.0, 200.0, 500.0, 900.0, 1200.0, 1800.0, 3000.0],
                            [1520.0, 1522.0, 1500.0, 1495.0, 1495.0, 1510.0, 1490.0, 1505.0])


@pytest.fixture(scope="module")
def ssp():
    return SoundSpeedProfile.from_file(DATA / "seagap" / "ss_prof.inp")


# --------------------------------------------------------------------------- references

def _layer_gradient(prof, z0, z1):
    zm = 0.5 * (z0 + z1)
    k = np.searchsorted(prof.depths, zm)
    if k == 0 or k == len(prof):
        return 0.0
    return float((prof.speeds[k] - prof.speeds[k - 1]) / (prof.depths[k] - prof.depths[k - 1]))


def _ode_ray(prof, z_start, turns, p, horizontal):
    """Shoot with the Hamiltonian ray equations in arc length s.

    State (x, z, zeta, t): dx/ds = c p, dz/ds = c zeta, dzeta/ds = -c'(z) / c**2,
    dt/ds = 1 / c. Only the start uses Snell (zeta from p); zeta is carried across
    knots by the integration, and reversed at a reflector.
    """
    x, z, t = 0.0, float(z_start), 0.0
    c = float(prof.speed(z))
    zeta = np.sign(turns[0] - z) * np.sqrt(1.0 / c**2 - p**2)
    for k, z_end in enumerate(turns):
        if k:
            zeta = -zeta  # specular reflection
        lo, hi = min(z, z_end), max(z, z_end)
        knots = prof.depths[(prof.depths > lo) & (prof.depths < hi)]
        stops = list(knots if z_end > z else knots[::-1]) + [z_end]
        for z_stop in stops:
            g = _layer_gradient(prof, z, z_stop)
            z0, c0 = z, float(prof.speed(z))

            def rhs(s, y, g=g, z0=z0, c0=c0):
                cz = c0 + g * (y[1] - z0)
                return [cz * p, cz * y[2], -g / cz**2, 1.0 / cz]

            def hit(s, y, z_stop=z_stop):
                return y[1] - z_stop

            hit.terminal = True
            s_max = 2.0 * (horizontal + abs(z_stop - z)) + 1.0
            sol = integrate.solve_ivp(rhs, (0.0, s_max), [x, z, zeta, t], method="DOP853",
                                      rtol=1e-12, atol=1e-12, events=hit)
            assert sol.status == 1, "the ray did not reach the next knot"
            x, _, zeta, t = sol.y_events[0][0]
            z = z_stop
    return x, t


def _snell_sum(prof, legs, p, dz=0.1):
    """Snell sum through thin constant-speed layers, Richardson-extrapolated.

    The midpoint sums at ``dz`` and ``dz / 2`` converge as ``dz**2`` (checked:
    the error falls 4x per halving); ``(4 f(dz/2) - f(dz)) / 3`` removes that term.
    """
    x1, t1 = _midpoint_sum(prof, legs, p, dz)
    x2, t2 = _midpoint_sum(prof, legs, p, dz / 2)
    return (4 * x2 - x1) / 3, (4 * t2 - t1) / 3


def _midpoint_sum(prof, legs, p, dz):
    """Horizontal run and time through thin constant-speed layers (midpoint speed)."""
    x = t = 0.0
    for top, bot in legs:
        edges = np.union1d(prof.depths[(prof.depths > top) & (prof.depths < bot)], [top, bot])
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            zz = np.linspace(a, b, max(1, int(np.ceil((b - a) / dz))) + 1)
            c = prof.speed(0.5 * (zz[:-1] + zz[1:]))
            h = np.diff(zz)
            s = np.sqrt(1.0 - (p * c) ** 2)
            x += np.sum(p * c * h / s)
            t += np.sum(h / (c * s))
    return x, t


# --------------------------------------------------------------------------- profile

@pytest.mark.parametrize(("depth", "speed", "match"), [
    ([0.0, 10.0, 10.0], [1500.0] * 3, r"depth\[2\] = 10.0 is not greater than depth\[1\]"),
    ([0.0, 20.0, 10.0], [1500.0] * 3, r"depth\[2\] = 10.0"),
    ([0.0, 10.0], [1500.0, -1.0], r"speed\[1\] = -1.0: expected a positive"),
    ([0.0, np.nan], [1500.0, 1500.0], r"depth\[1\] = nan: expected a finite"),
    ([0.0, 10.0], [1500.0, np.inf], r"speed\[1\] = inf"),
    ([0.0, 10.0], [1500.0], "same length, got 2 and 1"),
    ([], [], "at least one knot"),
    ([[0.0, 1.0]], [[1500.0, 1500.0]], r"1-D sequence, got shape \(1, 2\)"),
    (["a", "b"], [1500.0, 1500.0], "expected a 1-D sequence of numbers"),
])
def test_profile_validation_names_index_and_value(depth, speed, match):
    with pytest.raises(ValueError, match=match):
        SoundSpeedProfile(depth, speed)


def test_speed_is_piecewise_linear_and_constant_beyond_the_ends():
    prof = SoundSpeedProfile([100.0, 200.0, 400.0], [1500.0, 1490.0, 1510.0])
    assert prof.speed([0.0, 100.0, 150.0, 300.0, 400.0, 9000.0]).tolist() == \
        [1500.0, 1500.0, 1495.0, 1500.0, 1510.0, 1510.0]
    assert len(prof) == 3 and not prof.depths.flags.writeable
    assert float(SoundSpeedProfile.constant(1480.0).speed(-5.0)) == 1480.0
    assert "3 knots" in repr(prof)


def test_harmonic_mean_is_the_vertical_time_average(ssp):
    # one linear layer: exact closed form
    prof = SoundSpeedProfile([0.0, 1000.0], [1500.0, 1480.0])
    exact = 1000.0 / (np.log(1480.0 / 1500.0) / (-0.02))
    assert prof.harmonic_mean(0.0, 1000.0) == pytest.approx(exact, rel=1e-14)
    # anywhere, either order, beyond the knots: against quadrature of 1/c
    for zt, zb in [(3.0, 2700.0), (2700.0, 3.0), (-50.0, 7000.0), (1234.5, 1236.0)]:
        lo, hi = min(zt, zb), max(zt, zb)
        pts = ssp.depths[(ssp.depths > lo) & (ssp.depths < hi)]
        edges = np.concatenate([[lo], pts, [hi]])
        t = sum(integrate.quad(lambda z: 1.0 / float(ssp.speed(z)), a, b, epsabs=0,
                               epsrel=1e-13)[0] for a, b in zip(edges[:-1], edges[1:],
                                                                strict=True))
        assert ssp.harmonic_mean(zt, zb) == pytest.approx((hi - lo) / t, rel=1e-12)
    # zero-length path: the speed there; vectorised
    hm = ssp.harmonic_mean([0.0, 500.0], [500.0, 500.0])
    assert hm[1] == ssp.speed(500.0) and hm.shape == (2,)


# --------------------------------------------------------------------------- files

def test_reads_the_seagap_and_obsrange_profiles(ssp):
    assert len(ssp) == 1301
    assert (ssp.depths[0], ssp.depths[-1]) == (0.0, 6500.0)
    assert (ssp.speeds[0], ssp.speeds[-1]) == (1526.998, 1568.78)
    # data/README.md: the harmonic mean of ss_prof.inp is ~1489 m/s to the transponders
    assert ssp.harmonic_mean(0.0, 2700.0) == pytest.approx(1489.0, abs=1.5)
    cc03 = SoundSpeedProfile.from_file(DATA / "obsrange" / "CC03_ssp.txt")  # has a header
    assert len(cc03) == 33 and cc03.depths[-1] == 5500.0
    assert (cc03.speeds[0], cc03.speeds[-1]) == (1540.71, 1549.05)


def test_from_file_formats(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("# CTD cast 7\nDepth [m], T, Sound speed [m/s]\n\n0, 20.1, 1521.5  # surface\n"
                 "10,20.0,1521.0\n  25 , 19.0 , 1519.0, extra\n")
    prof = SoundSpeedProfile.from_file(f, columns=(0, 2))
    assert prof.depths.tolist() == [0.0, 10.0, 25.0]
    assert prof.speeds.tolist() == [1521.5, 1521.0, 1519.0]
    assert prof.source == str(f)


@pytest.mark.parametrize(("text", "match"), [
    ("0 1500\n10 1501\nabc def\n", r"line 3: expected numbers in columns 0 and 1"),
    ("0 1500\n10\n", r"line 2: expected at least 2 fields"),
    ("0 1500\n10 1501\n10 1502\n", r"line 3: depth 10.0 is not greater than the previous "
                                   r"depth 10.0 \(line 2\)"),
    ("0 1500\n10 -3\n", r"line 2: sound speed -3 outside \[1300, 1800\] m/s"),
    ("0 1500\n10 1\n", r"line 2: sound speed 1 outside .*physically possible"),
    ("0 1500\n10 nan\n", r"line 2: expected finite numbers"),
    ("# nothing\n\n", "no data lines found"),
])
def test_from_file_errors_name_file_and_line(tmp_path, text, match):
    f = tmp_path / "bad.txt"
    f.write_text(text)
    with pytest.raises(InputError, match=match) as err:
        SoundSpeedProfile.from_file(f)
    assert str(f) in str(err.value)


# --------------------------------------------------------------------------- WOA09

def test_woa09_at_the_obsrange_cc03_site():
    prof = SoundSpeedProfile.from_woa09(*CC03, directory=WOA09)
    assert prof.depths[-1] >= 4000.0 and len(prof) == 33
    assert np.all((prof.speeds > 1480.0) & (prof.speeds < 1560.0))
    assert "cell (-4.5, 227.5)" in prof.source
    # the deep water agrees with the profile OBSrange used for CC03 (upper ocean: season)
    used = SoundSpeedProfile.from_file(DATA / "obsrange" / "CC03_ssp.txt")
    deep = used.depths >= 1000.0
    assert np.abs(prof.speed(used.depths[deep]) - used.speeds[deep]).max() < 0.3


def test_woa09_directory_from_the_environment(monkeypatch):
    from bayes_mpem.acoustics import profile as woa09

    monkeypatch.delenv(WOA09_ENV, raising=False)
    # installed (or in the source tree) the atlas is found without being told where
    assert SoundSpeedProfile.from_woa09(*CC03).speeds.size == 33
    monkeypatch.setattr(woa09, "bundled_woa09", lambda: None)
    with pytest.raises(FileNotFoundError, match=f"pass directory=.*{WOA09_ENV}"):
        SoundSpeedProfile.from_woa09(*CC03)
    monkeypatch.setenv(WOA09_ENV, str(WOA09))
    assert SoundSpeedProfile.from_woa09(CC03[0], CC03[1] + 360.0).speeds.size == 33
    with pytest.raises(FileNotFoundError, match="lev_latlonZ.mat not found"):
        SoundSpeedProfile.from_woa09(*CC03, directory=WOA09 / "nowhere")
    with pytest.raises(ValueError, match="expected -90 <= lat <= 90"):
        SoundSpeedProfile.from_woa09(91.0, 0.0)


def test_woa09_missing_levels_and_cells(tmp_path):
    from scipy.io import savemat

    lat = np.repeat(np.arange(-895, 900, 10), 360).astype(np.int16)
    lon = np.tile(np.arange(5, 3600, 10), 180).astype(np.uint16)
    c = np.zeros((lat.size, 4), np.uint16)  # 0: missing everywhere...
    k = np.flatnonzero((lat == 5) & (lon == 105))[0]  # ...except the cell (0.5, 10.5)
    c[k] = [52000, 49000, 50000, 0]  # three levels above the seafloor
    savemat(tmp_path / "lev_latlonZ.mat", {"lat": lat[:, None], "lon": lon[:, None],
                                           "z": np.array([[0, 100, 500, 1000]], np.uint16)})
    savemat(tmp_path / "lev_ann.mat", {"c": c})
    prof = SoundSpeedProfile.from_woa09(0.2, 10.2, tmp_path)
    assert prof.depths.tolist() == [0.0, 100.0, 500.0]
    assert prof.speeds.tolist() == [1520.0, 1490.0, 1500.0]
    with pytest.raises(ValueError, match=r"nearest cell with data, \(0.5, 10.5\), is \d+ km"):
        SoundSpeedProfile.from_woa09(10.0, 10.5, tmp_path)


# --------------------------------------------------------------------------- CTD

def test_from_ctd_without_gsw_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "gsw", None)
    with pytest.raises(ImportError, match="pip install gsw"):
        SoundSpeedProfile.from_ctd([0.0, 100.0], [35.0, 35.0], [20.0, 15.0], 36.0, 142.0)


def test_from_ctd_with_gsw():
    gsw = pytest.importorskip("gsw")
    p = np.array([0.0, 500.0, 1000.0, 2000.0, 3000.0])
    sp = np.array([34.5, 34.3, 34.4, 34.6, 34.7])
    t = np.array([20.0, 8.0, 4.0, 2.5, 1.8])
    prof = SoundSpeedProfile.from_ctd(p, sp, t, 36.16, 142.08)
    assert np.all((prof.speeds > 1470.0) & (prof.speeds < 1530.0))
    assert prof.depths[0] == pytest.approx(0.0, abs=1e-9)
    assert np.all(prof.depths[1:] < p[1:]) and np.all(prof.depths[1:] > 0.98 * p[1:])
    sa = gsw.SA_from_SP(sp, p, 142.08, 36.16)
    assert prof.speeds == pytest.approx(gsw.sound_speed(sa, gsw.CT_from_t(sa, t, p), p))
    with pytest.raises(ValueError, match=r"pressure_dbar\[2\] = 500.0 is not greater"):
        SoundSpeedProfile.from_ctd([0.0, 500.0, 500.0], [35.0] * 3, [10.0] * 3, 36.0, 142.0)


# --------------------------------------------------------------------------- straight line

def test_homogeneous_medium_gives_the_straight_line():
    c = 1500.0
    prof = SoundSpeedProfile.constant(c)
    z_a = np.array([0.0, 2700.0, 100.0, 100.0, 100.0, 2700.0, 5.0, 2000.0, 50.0])
    z_b = np.array([2700.0, 0.0, 100.0, 100.001, 2000.0, 2699.999, 5.0, 1000.0, 50.0])
    h = np.array([3000.0, 3000.0, 5000.0, 5000.0, 0.0, 8000.0, 0.0, 1e-6, 1e6])
    ray = direct_ray(prof, z_a, z_b, h)
    assert ray.valid.all()
    assert np.abs(c * ray.time - np.hypot(h, z_b - z_a)).max() <= 1e-6
    # angles from the downward vertical: the chord's
    chord = np.degrees(np.arctan2(h, z_b - z_a))
    chord[(h == 0) & (z_a == z_b)] = 0.0
    assert np.abs(ray.launch_angle - chord).max() <= 1e-6
    assert ray.arrival_angle == pytest.approx(ray.launch_angle, abs=1e-9)
    assert ray.p == pytest.approx(np.sin(np.radians(chord)) / c, abs=1e-15)
    # a sweep of distances, vertical to near horizontal
    hh = np.geomspace(1e-9, 1e7, 60)
    for dz in (1900.0, 0.5, 1e-3):
        ray = direct_ray(prof, 100.0, 100.0 + dz, hh)
        assert np.abs(c * ray.time - np.hypot(hh, dz)).max() <= 1e-6


@pytest.mark.parametrize("plane_depth", [0.0, 35.0])
def test_homogeneous_surface_bounce_is_the_image_method(plane_depth):
    c = 1480.0
    prof = SoundSpeedProfile.constant(c)
    rng = np.random.default_rng(1)
    z_beacon = rng.uniform(plane_depth, 3000.0, 500)
    z_vehicle = rng.uniform(plane_depth, 3000.0, 500)
    h = np.concatenate([[0.0, 1e-3, 1e5], rng.uniform(0.0, 8000.0, 497)])
    z_vehicle[:3] = [plane_depth, 10.0 + plane_depth, 2999.0]
    dz, d0 = z_beacon - z_vehicle, z_beacon - plane_depth
    bounce = surface_bounce_ray(prof, z_beacon, z_vehicle, h, plane_depth)
    direct = direct_ray(prof, z_beacon, z_vehicle, h)
    assert bounce.valid.all() and direct.valid.all()
    double = geometry.multipath_range(h, dz, d0, "double")
    triangle = geometry.multipath_range(h, dz, d0, "triangle")
    assert np.abs(c * bounce.time - double).max() <= 1e-6
    assert np.abs(c * 0.5 * (bounce.time + direct.time) - triangle).max() <= 1e-6
    # up at the start, down at the end, mirror angles
    assert np.all(bounce.launch_angle >= 90.0) and np.all(bounce.arrival_angle <= 90.0)
    assert bounce.launch_angle == pytest.approx(180.0 - bounce.arrival_angle, abs=1e-6)


# --------------------------------------------------------------------------- layered media

@pytest.mark.parametrize(("z_a", "z_b", "h"), [(5.0, 2700.0, 3000.0), (2650.0, 40.0, 1500.0),
                                               (2700.0, 2000.0, 100.0),
                                               (1000.0, 1100.0, 900.0)])
def test_direct_ray_matches_the_ray_equations(ssp, z_a, z_b, h):
    for prof in (LAYERED, ssp):
        ray = direct_ray(prof, z_a, z_b, h)
        assert ray.valid
        x, t = _ode_ray(prof, z_a, [z_b], float(ray.p), h)
        assert abs(x - h) <= 1e-5
        assert abs(t - float(ray.time)) <= 1e-9
        xs, ts = _snell_sum(prof, [(min(z_a, z_b), max(z_a, z_b))], float(ray.p))
        assert abs(xs - h) <= 1e-5
        assert abs(ts - float(ray.time)) <= 1e-9


@pytest.mark.parametrize(("z_a", "z_b", "h", "plane"), [(2700.0, 10.0, 3000.0, 0.0),
                                                        (1500.0, 2400.0, 6000.0, 0.0),
                                                        (2000.0, 2100.0, 500.0, 700.0)])
def test_surface_bounce_matches_the_ray_equations(ssp, z_a, z_b, h, plane):
    for prof in (LAYERED, ssp):
        ray = surface_bounce_ray(prof, z_a, z_b, h, plane)
        assert ray.valid
        x, t = _ode_ray(prof, z_a, [plane, z_b], float(ray.p), h)
        assert abs(x - h) <= 1e-5
        assert abs(t - float(ray.time)) <= 1e-9
        xs, ts = _snell_sum(prof, [(plane, z_a), (plane, z_b)], float(ray.p))
        assert abs(xs - h) <= 1e-5
        assert abs(ts - float(ray.time)) <= 1e-9


def test_many_rays_at_once_match_the_references_and_single_rays():
    rng = np.random.default_rng(7)
    n = 40
    z_a, z_b = rng.uniform(-20.0, 3200.0, n), rng.uniform(-20.0, 3200.0, n)
    h = rng.uniform(0.0, 4000.0, n)
    ray = direct_ray(LAYERED, z_a, z_b, h)
    assert ray.valid.sum() >= 20
    for i in np.flatnonzero(ray.valid):
        lo, hi = min(z_a[i], z_b[i]), max(z_a[i], z_b[i])
        # shoot from the faster end: a ray grazing there is then well conditioned
        start, end = (z_a[i], z_b[i]) if LAYERED.speed(z_a[i]) >= LAYERED.speed(z_b[i]) \
            else (z_b[i], z_a[i])
        x, t = _ode_ray(LAYERED, start, [end], ray.p[i], h[i])
        assert abs(x - h[i]) <= 1e-5 and abs(t - ray.time[i]) <= 1e-9
        c_max = max(LAYERED.speed([lo, hi]).max(),
                    LAYERED.speeds[(LAYERED.depths > lo) & (LAYERED.depths < hi)].max(initial=0))
        if ray.p[i] * c_max < 0.999:  # the midpoint sums lose their order near grazing
            xs, ts = _snell_sum(LAYERED, [(lo, hi)], ray.p[i])
            assert abs(xs - h[i]) <= 1e-5 and abs(ts - ray.time[i]) <= 1e-9
        one = direct_ray(LAYERED, z_a[i], z_b[i], h[i])
        assert float(one.time) == pytest.approx(ray.time[i], rel=1e-13, abs=0)
    # broadcasting keeps the shape
    grid = direct_ray(LAYERED, 10.0, np.array([[500.0], [2500.0]]), np.array([0.0, 300.0, 900.0]))
    assert grid.time.shape == (2, 3) and grid.valid.all()


def _ship_to_transponder(rng, n, depth, reach):
    """GNSS-A legs: a heaving transducer near the surface, one transponder, offsets to reach."""
    top = rng.normal(3.0, 1.0, n)  # some above the profile's first knot
    bot = np.full(n, depth)
    h = rng.uniform(0.0, reach, n)
    h[:3] = 0.0, 1e-3, reach
    return top, bot, h


def _sampled(z, c):
    return SoundSpeedProfile(z, c, source="test")


_Z = np.arange(0.0, 3001.0, 10.0)
_ETA = 2.0 * (_Z - 1300.0) / 1300.0
SHARED_CASES = {  # profiles with many knots (where a shared table pays), fastest point varied
    "seagap": None,  # the shipped SeaGap cast (the fixture)
    "munk": _sampled(_Z, 1500.0 * (1.0 + 0.00737 * (_ETA - 1.0 + np.exp(-_ETA)))),
    "duct": _sampled(_Z, np.where(_Z < 80.0, 1510.0 + 0.02 * _Z,
                                  1511.6 - 0.03 * (_Z - 80.0) + 1.2e-5 * (_Z - 80.0) ** 2)),
    "polar": _sampled(_Z, 1440.0 + 0.017 * _Z + 2e-6 * _Z**2),  # fastest at the bottom
    "short": _sampled(_Z[:200], 1500.0 * (1.0 + 0.00737 * (_ETA - 1.0 + np.exp(-_ETA))[:200])),
}


@pytest.mark.parametrize("name", list(SHARED_CASES))
def test_rays_sharing_their_layers_match_the_exact_solver(ssp, name):
    from bayes_mpem.acoustics import eigenray
    prof = SHARED_CASES[name] or ssp
    rng = np.random.default_rng(11)
    top, bot, h = _ship_to_transponder(rng, 400, 2900.0, 1.6 * 2900.0)
    v = bot - top
    p, t = np.full(h.size, np.nan), np.full(h.size, np.nan)
    solved = eigenray._trace_shared(prof, top, bot, h, v, 1e-9, 100, p, t)
    assert solved.mean() > 0.9  # the table holds the array's rays
    p_ref, t_ref = eigenray._trace_blocks(prof, [(top, bot)], h, v, 1e-9, 100)
    assert np.isfinite(t_ref[solved]).all()
    assert t[solved] == pytest.approx(t_ref[solved], rel=1e-13, abs=0)
    assert p[solved] == pytest.approx(p_ref[solved], rel=1e-12, abs=1e-17)
    # through the public solver, with rays the table cannot hold (near grazing, or turning)
    far = np.concatenate([h, [5e4, 2e5]])
    top2, bot2 = np.concatenate([top, [3.0, 3.0]]), np.concatenate([bot, [2900.0, 2900.0]])
    ray = direct_ray(prof, top2, bot2, far)
    p_ref, t_ref = eigenray._trace_blocks(prof, [(top2, bot2)], far, bot2 - top2, 1e-9, 100)
    assert np.array_equal(np.isnan(ray.time), np.isnan(t_ref))
    ok = ~np.isnan(t_ref)
    assert ray.time[ok] == pytest.approx(t_ref[ok], rel=1e-13, abs=0)


def test_rays_near_grazing_leave_the_others_their_table(ssp):
    from bayes_mpem.acoustics import eigenray
    h = np.linspace(0.0, 8000.0, 2000)  # out to 3 depths: the farthest rays near grazing
    top, bot = np.full(h.size, 0.0), np.full(h.size, 2700.0)
    p, t = np.full(h.size, np.nan), np.full(h.size, np.nan)
    solved = eigenray._trace_shared(ssp, top, bot, h, bot - top, 1e-9, 100, p, t)
    assert 0.9 < solved.mean() < 1.0 and solved[: int(0.9 * h.size)].all()
    p_ref, t_ref = eigenray._trace_blocks(ssp, [(top, bot)], h, bot - top, 1e-9, 100)
    assert t[solved] == pytest.approx(t_ref[solved], rel=1e-13, abs=0)
    ray = direct_ray(ssp, top, bot, h)  # the rest by the block solver
    assert np.array_equal(np.isnan(ray.time), np.isnan(t_ref))
    assert ray.time[~solved] == pytest.approx(t_ref[~solved], rel=1e-15, nan_ok=True)


def test_rays_without_shared_layers_are_left_to_the_exact_solver():
    from bayes_mpem.acoustics import eigenray
    rng = np.random.default_rng(5)
    n = 200  # a vehicle at any depth: the ends hold more layers than the rays share
    top, bot, h = rng.uniform(0.0, 2500.0, n), np.full(n, 2900.0), rng.uniform(0, 3000.0, n)
    p, t = np.full(n, np.nan), np.full(n, np.nan)
    assert not eigenray._trace_shared(LAYERED, top, bot, h, bot - top, 1e-9, 100, p, t).any()
    assert np.isnan(t).all()
    ray = direct_ray(LAYERED, top, bot, h)
    p_ref, t_ref = eigenray._trace_blocks(LAYERED, [(top, bot)], h, bot - top, 1e-9, 100)
    assert np.array_equal(ray.time, t_ref, equal_nan=True)


def test_vertical_ray_time_is_the_vertical_slowness_integral(ssp):
    z_a, z_b = np.array([0.0, 2700.0, 3.0, 7000.0]), np.array([2700.0, 0.0, 4.5, -10.0])
    ray = direct_ray(ssp, z_a, z_b, 0.0)
    assert ray.valid.all() and np.all(ray.p == 0)
    expected = np.abs(z_b - z_a) / ssp.harmonic_mean(z_a, z_b)
    assert ray.time == pytest.approx(expected, rel=1e-13)
    assert ray.launch_angle.tolist() == [0.0, 180.0, 0.0, 180.0]


def test_swapping_the_ends_gives_the_same_ray(ssp):
    rng = np.random.default_rng(3)
    z_a, z_b = rng.uniform(0.0, 2800.0, 300), rng.uniform(0.0, 2800.0, 300)
    h = rng.uniform(0.0, 6000.0, 300)
    for trace in (direct_ray, surface_bounce_ray):
        ab, ba = trace(ssp, z_a, z_b, h), trace(ssp, z_b, z_a, h)
        assert np.array_equal(ab.valid, ba.valid) and ab.valid.sum() > 100
        ok = ab.valid
        assert ab.time[ok] == pytest.approx(ba.time[ok], rel=1e-13, abs=0)
        assert ab.p[ok] == pytest.approx(ba.p[ok], rel=1e-9)
        assert ab.launch_angle[ok] == pytest.approx(180.0 - ba.arrival_angle[ok], abs=1e-7)


def test_horizontal_run_increases_with_the_ray_parameter(ssp):
    for prof, (za, zb) in ((ssp, (2700.0, 0.0)), (LAYERED, (100.0, 2900.0))):
        lo, hi = min(za, zb), max(za, zb)
        c_max = max(prof.speed([lo, hi]).max(),
                    prof.speeds[(prof.depths > lo) & (prof.depths < hi)].max())
        p = np.linspace(0.0, 1.0 / c_max, 2001)
        x, t = shoot(prof, za, zb, p)
        assert np.all(np.isfinite(x)) and x[0] == 0.0
        assert np.all(np.diff(x) > 0) and np.all(np.diff(t) > 0)
        # dT/dX = p along the family of rays (Snell), checked by finite differences
        # (away from grazing, where X(p) has a square-root singularity)
        mid = 0.5 * (p[1:] + p[:-1])
        away = mid * c_max < 0.99
        assert (np.diff(t) / np.diff(x))[away] == pytest.approx(mid[away], rel=1e-5, abs=0)
        # beyond 1/c_max the ray turns: NaN, never an answer
        x_out, t_out = shoot(prof, za, zb, [1.0001 / c_max, -1e-6])
        assert np.isnan(x_out).all() and np.isnan(t_out).all()


def test_shoot_at_grazing_many_ranges_at_once():
    z_a, z_b = np.array([1200.0, 1000.0, 0.0, 600.0]), np.array([2900.0, 1500.0, 60.0, 850.0])
    p = 1.0 / np.array([1510.0, 1510.0, 1522.0, 1495.0])  # 1 / c_max of each range
    x, t = shoot(LAYERED, z_a, z_b, p)
    for i in range(3):
        xi, ti = shoot(LAYERED, z_a[i], z_b[i], p[i])
        assert np.isfinite(xi) and x[i] == pytest.approx(float(xi), rel=1e-14)
        assert t[i] == pytest.approx(float(ti), rel=1e-14)
    # at the top of a constant-speed layer the grazing ray runs along it for ever
    assert np.isinf(x[3]) and np.isinf(t[3])


def test_turning_rays_are_flagged_not_approximated():
    # speed increasing downward below 1200 m: a ray from 2900 m to 1200 m can only
    # reach out to X(1/c(1200)); beyond that it would have to turn
    prof = SoundSpeedProfile([0.0, 1200.0, 3000.0], [1520.0, 1510.0, 1490.0])
    x_max, _ = shoot(prof, 1200.0, 2900.0, 1.0 / 1510.0)
    h = x_max * np.array([0.5, 0.999999, 1.0, 1.000001, 2.0])
    ray = direct_ray(prof, 2900.0, 1200.0, h)
    assert ray.valid.tolist() == [True, True, True, False, False]
    for name in ("time", "p", "launch_angle", "arrival_angle"):
        assert np.isnan(getattr(ray, name)[~ray.valid]).all()
    assert ray.arrival_angle[2] == pytest.approx(180.0 - 90.0, abs=1e-6)
    # both ends at one depth: only a constant-speed neighbourhood has a direct ray
    flat = direct_ray(LAYERED, [700.0, 100.0, 100.0, 5000.0], [700.0, 100.0, 100.0, 5000.0],
                      [2000.0, 0.0, 10.0, 10.0])
    assert flat.valid.tolist() == [True, True, False, True]
    assert flat.time[0] == 2000.0 / 1495.0 and flat.time[1] == 0.0
    # a fast layer of finite thickness is reached at any distance
    assert direct_ray(LAYERED, 600.0, 850.0, 1e6).valid


def test_bad_ray_input_is_rejected():
    prof = SoundSpeedProfile.constant(1500.0)
    with pytest.raises(ValueError, match=r"horizontal: expected distances >= 0 m, got -1.0 at "
                                         r"flat index 1"):
        direct_ray(prof, 0.0, 100.0, [10.0, -1.0])
    with pytest.raises(ValueError, match=r"z_b: expected finite numbers, got nan"):
        direct_ray(prof, 0.0, [100.0, np.nan], 10.0)
    with pytest.raises(ValueError, match="must broadcast together"):
        direct_ray(prof, [0.0, 1.0], [1.0, 2.0, 3.0], 10.0)
    with pytest.raises(ValueError, match=r"reflector must be above both ends; at flat index 1 "
                                         r"plane_depth = 0.0 m but z_a = -5.0 m"):
        surface_bounce_ray(prof, [10.0, -5.0], 20.0, 10.0)
    with pytest.raises(ValueError, match="tol: expected a positive number"):
        direct_ray(prof, 0.0, 100.0, 10.0, tol=0.0)
