"""The GNSS-A simulator's sound-speed field, gradients, tracks and truth."""

import json

import numpy as np
import pytest

from bayes_mpem.acoustics.profile import SoundSpeedProfile
from bayes_mpem.acoustics.turning import direct_times
from bayes_mpem.io.garpos import read_garpos
from bayes_mpem.io.gnatss import read_gnatss
from bayes_mpem.survey_in.gnssa_simulate import (
    SoundSpeedField,
    reference_profile,
    simulate_gnssa,
)

QUIET = dict(p_spurious=0.0, p_missing=0.0, sigma=1e-9)


def test_the_field_leaves_track_noise_and_replies_as_they_were():
    """The field's phases come from a child generator: same seed, same ship and replies."""
    a = simulate_gnssa(hours=0.5, rng=3)
    b = simulate_gnssa(hours=0.5, rng=3, speed_model="field", gradients=True)
    for c in ("e_tx", "n_tx", "u_tx", "head_tx", "t_tx", "transponder"):
        assert (a.pings[c] == b.pings[c]).all(), c
    assert (a.truth["spurious"] == b.truth["spurious"]).all()
    assert not np.allclose(a.pings["twtt"], b.pings["twtt"])
    assert "field" not in a.truth and "series" in b.truth


def test_first_order_time_change_matches_the_exact_ray():
    """A surface-intensified change of 2 m/s: the chord integral is within 0.5 us of the
    eigenray through the changed profile, out to 45 degrees (the change is ~400 us)."""
    f = SoundSpeedField(amplitudes=(2.0,), periods=(1e12,), phases=(np.pi / 2,), decay=400.0,
                        shallow=0.0, deep=0.0, shallow_decay=300.0, gradient_period=1e5,
                        gradient_phases=(0.0, 0.0), centre=(0.0, 0.0), depth=1500.0)
    prof = reference_profile(1700.0)
    z, c = prof["depth"].to_numpy(), prof["sound_speed"].to_numpy()
    h, zs, zx = np.array([0.0, 500.0, 1000.0, 1500.0]), np.full(4, 2.0), np.full(4, 1500.0)
    t0 = direct_times(SoundSpeedProfile(z, c), zs, zx, h).time
    t1 = direct_times(SoundSpeedProfile(z, c + 2.0 * np.exp(-z / 400.0)), zs, zx, h).time
    dt = f.delta_time(np.zeros(4), (h, np.zeros(4), -zs), (0.0, 0.0, -1500.0))
    assert np.all(np.abs(t1 - t0) > 3e-4)
    np.testing.assert_allclose(dt, t1 - t0, atol=5e-7)


def test_gradients_act_as_garpos_gamma_says():
    """The travel-time change of the gradients, traced along the chord, against GARPOS's
    gamma = a1 (p - c)/L + a2 (x - c)/L from the truth's a1, a2: the same to 1 %."""
    kw = dict(hours=1.0, speed_model="field", track="star+circle", rng=4, **QUIET)
    d = {}
    for mode in ("ray", "gamma"):
        on = simulate_gnssa(gradients=True, travel_time=mode, **kw)
        off = simulate_gnssa(gradients=False, travel_time=mode, **kw)
        d[mode] = on.pings["twtt"].to_numpy() - off.pings["twtt"].to_numpy()
    assert np.abs(d["ray"]).max() > 1e-4
    slope = np.polyfit(d["gamma"], d["ray"], 1)[0]
    assert slope == pytest.approx(1.0, abs=0.01)
    assert np.std(d["ray"] - d["gamma"]) < 0.02 * np.std(d["ray"])


def test_no_gradients_means_zero_gradient_truth():
    sim = simulate_gnssa(hours=0.5, speed_model="field", rng=1)
    rec = sim.truth_record()
    assert rec["gradients"] is None
    assert np.all(sim.truth["series"][["grad1_east", "grad2_north"]].to_numpy() == 0.0)
    dv = np.asarray(rec["sound_speed"]["series"]["dV0_m_s"])
    assert 0.01 < np.ptp(dv) < 3.0  # m/s: the depth-averaged change, smaller than the surface's


def test_tracks():
    r = np.hypot(*[simulate_gnssa(hours=0.5, track="circle", track_radius=1000.0, rng=1)
                   .pings[c].to_numpy() for c in ("e_tx", "n_tx")])
    assert r.min() > 990.0 and r.max() < 1010.0
    p = simulate_gnssa(hours=1.0, track="station", rng=1).pings
    assert np.abs(p[["e_tx", "n_tx"]].to_numpy()).max() < 51.0
    with pytest.raises(ValueError, match="track"):
        simulate_gnssa(hours=0.2, track="zigzag")
    with pytest.raises(ValueError, match="speed_model='field'"):
        simulate_gnssa(hours=0.2, gradients=True)


@pytest.mark.parametrize("fmt", ["garpos", "gnatss"])
def test_written_campaign_reads_back_with_its_truth(tmp_path, fmt):
    sim = simulate_gnssa(n_transponders=3, hours=0.3, rng=2, speed_model="field",
                         gradients=True, origin=(38.0, 143.0, 20.0))
    paths = sim.write(tmp_path, fmt)
    raw = (read_garpos if fmt == "garpos" else read_gnatss)(paths["survey"])
    assert len(raw.pings) == len(sim.pings)
    truth = json.loads(paths["truth"].read_text())
    assert truth["format"] == fmt and set(truth["transponders"]) == {"M01", "M02", "M03"}
    assert truth["gradients"]["unit"] == "(m/s)/km"
    assert truth["spurious"]["n"] == int(sim.truth["spurious"].sum())
    centre = sim.truth["transponders"].mean()
    assert truth["array_centre"]["up"] == pytest.approx(centre["up"])
