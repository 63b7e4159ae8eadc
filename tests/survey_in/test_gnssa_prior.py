"""The site file's sigmas above 0 as Gaussian priors on the positions (GARPOS's a priori)."""

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.cli import main
from bayes_mpem.exceptions import InputError
from bayes_mpem.io.garpos import read_garpos, write_garpos
from bayes_mpem.survey_in.array import _position_parameters, locate_array
from bayes_mpem.survey_in.array_sampling import ArrayLogPosterior
from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey, site_priors
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa
from bayes_mpem.survey_in.result import positions_line

IDS = ["A", "B", "C"]


def _tp():
    return pd.DataFrame(np.zeros((3, 3)), index=IDS, columns=["east", "north", "up"])


def test_the_parameters_are_garpos_s_dpos_and_a_common_dcentpos():
    sd = np.array([[1.0, 2.0, np.inf], [1.0, 2.0, 3.0], [np.nan, 2.0, 3.0]])
    c = np.array([0.5, 0.0, 1.0])
    mask = np.zeros((3, 3), bool)
    mask[1, 0] = True  # B's own east held, but it moves with the common east shift
    G, P = _position_parameters(sd, c, _tp(), IDS, mask, False)
    assert G.shape == (9, 10)  # 8 offsets, then the east and up shifts
    np.testing.assert_array_equal(G[:, 8], np.tile([1.0, 0.0, 0.0], 3))
    np.testing.assert_array_equal(G[:, 9], np.tile([0.0, 0.0, 1.0], 3))
    assert np.count_nonzero(G[3]) == 1 and G[3, 8] == 1.0  # B east: the shift only
    # diagonal: the offsets' sds (none for A up and C east), then the shifts'
    np.testing.assert_allclose(np.diag(P), [1.0, 0.25, 0.0, 0.25, 1 / 9, 0.0, 0.25, 1 / 9,
                                            4.0, 1.0])
    assert np.count_nonzero(P - np.diag(np.diag(P))) == 0
    # where every coordinate has a prior, the positions' is diag(sd^2) plus the shift's
    G, P = _position_parameters(np.full((3, 3), 2.0), c, _tp(), IDS, np.zeros((3, 3), bool),
                                False)
    axis = np.tile(np.arange(3), 3)
    cov = 4.0 * np.eye(9) + np.where(axis[:, None] == axis[None, :], c[axis][:, None] ** 2, 0)
    np.testing.assert_allclose(G @ np.diag(1 / np.diag(P)) @ G.T, cov, atol=1e-12)
    # the shift's prior under a fixed geometry is dCentPos's own; a held axis is not a parameter
    G, P = _position_parameters(None, [3.0, 3.0, 2.0], _tp(), IDS,
                                np.tile([0, 0, 1], (3, 1)) > 0, True)
    assert G.shape == (9, 2)
    np.testing.assert_allclose(P, np.diag([1 / 9, 1 / 9]))
    G, P = _position_parameters(np.full((3, 3), np.inf), None, _tp(), IDS, mask, False)
    assert P is None and G.shape == (9, 8)


@pytest.mark.parametrize("sd, centre, match", [
    (np.zeros((3, 3)), None, "prior_sd: expected sds above 0"),
    (-np.ones((3, 3)), None, "prior_sd: expected sds above 0"),
    (np.ones((2, 3)), None, r"prior_sd: expected a \(3, 3\) array"),
    (None, [1.0, np.nan, 1.0], "centre_sd: expected three sds"),
    (None, [1.0, 1.0], "centre_sd: expected three sds"),
])
def test_bad_priors_are_named(sd, centre, match):
    with pytest.raises(InputError, match=match):
        _position_parameters(sd, centre, _tp(), IDS, np.zeros((3, 3), bool), False)


@pytest.fixture(scope="module")
def short_star():
    """Half an hour of a star: one transponder's coordinates barely constrained."""
    sim = simulate_gnssa(n_transponders=3, hours=0.5, rng=31)
    return sim, array_shots(sim.raw())


def test_a_prior_adds_its_precision_to_the_data_s(short_star):
    """Unpenalised speed, independent replies: the model-based precisions add.

    The prior positions 3 cm from the truth, within the prior's 5 cm (the simulator's are
    metres off: a 5 cm prior about them is wrong, and the fit's sigma says so).
    """
    sim, shots = short_star
    true = sim.truth["transponders"][["east", "north", "up"]]
    tp = true + np.random.default_rng(0).normal(0.0, 0.03, (3, 3))
    free = locate_array(shots, tp, speed_intervals=0)
    sd = np.full((3, 3), 0.05)
    with_prior = locate_array(shots, tp, speed_intervals=0, prior_sd=sd)
    data_prec = np.linalg.inv(free.cov_model[:9, :9])
    expect = np.linalg.inv(data_prec + np.eye(9) / 0.05**2)
    got = with_prior.cov_model[:9, :9]
    np.testing.assert_allclose(np.sqrt(np.diag(got)), np.sqrt(np.diag(expect)), rtol=0.05)
    assert np.all(with_prior.sd < free.sd) and np.all(with_prior.sd < 0.05)
    # the estimate moves towards the prior position, as a precision-weighted mean would
    moved_free = np.abs(free.enu - free.start)
    moved = np.abs(with_prior.enu - with_prior.start)
    assert np.sum(moved) < np.sum(moved_free)
    rec = with_prior.model["positions"]["prior"]
    assert rec["n_with_prior"] == 9 and rec["transponder_sd"]["M01"] == [0.05] * 3


@pytest.mark.parametrize("intervals", [None, 0])
def test_a_vague_prior_changes_nothing_and_a_sharp_one_holds(short_star, intervals):
    sim, shots = short_star
    tp = sim.header["transponders"]
    kw = dict(speed_intervals=intervals, correlation=None, gradients=False)
    free = locate_array(shots, tp, **kw)
    vague = locate_array(shots, tp, prior_sd=np.full((3, 3), 1e5), **kw)
    np.testing.assert_allclose(vague.enu, free.enu, atol=1e-5)
    np.testing.assert_allclose(vague.sd, free.sd, rtol=1e-3)
    sharp = locate_array(shots, tp, prior_sd=np.full((3, 3), 1e-4), **kw)
    np.testing.assert_allclose(sharp.enu, sharp.start, atol=5e-4)
    assert np.all(sharp.sd <= 1.01e-4)


def test_a_campaign_written_for_garpos_carries_its_prior_sds(tmp_path):
    sim = simulate_gnssa(n_transponders=3, hours=0.4, rng=32, prior_sd=(2.0, 2.0, 4.0))
    site = sim.write(tmp_path / "g", "garpos")["survey"]
    raw = read_garpos(site)
    sd, centre = site_priors(raw.header)
    np.testing.assert_array_equal(sd, np.tile([2.0, 2.0, 4.0], (3, 1)))
    assert centre is None
    res = locate_array_survey(raw)
    prior = res.summary["positions"]["prior"]
    assert prior["transponder_sd"]["M02"] == [2.0, 2.0, 4.0] and prior["centre_sd"] == [0.0] * 3
    assert "Gaussian priors from the site file's sigmas on 9 parameters (sd 2-4 m)" in \
        positions_line(res.summary)
    off = locate_array_survey(raw, position_prior="off")
    assert off.summary["positions"]["prior"] is None and positions_line(off.summary) is None
    assert not np.array_equal(off.fits["array"].enu, res.fits["array"].enu)
    with pytest.raises(InputError, match="position_prior"):
        locate_array_survey(raw, position_prior="on")


def test_one_straight_pass_is_held_near_the_prior_positions(tmp_path):
    """The single pass that failed by tens of metres (docs/gnssa.md, "Short campaigns").

    Eight minutes of a star over three transponders (74 replies): without the priors the
    sds are 10-60 m (the EM's answer tens of metres off, and honest about it); with them
    every coordinate is within 3 sd of the truth with sds under the prior's, and the line
    names the coordinates the prior, not the shots, determines.
    """
    sim = simulate_gnssa(n_transponders=3, hours=0.14, rng=5, depth=1500.0)
    site = sim.write(tmp_path / "g", "garpos")["survey"]
    raw = read_garpos(site)
    true = sim.truth["transponders"][["east", "north", "up"]].to_numpy()
    free = locate_array_survey(raw, position_prior="off").fits["array"]
    assert np.all(free.sd > 9.0)
    res = locate_array_survey(raw)
    fit = res.fits["array"]
    z = (fit.enu - true) / fit.sd
    assert np.all(np.abs(z) < 3.0), z
    assert np.all(fit.sd < np.array([3.0, 3.0, 5.0]))
    assert "the prior, not the shots, gives most of the precision of M01 north" in \
        positions_line(res.summary)


def test_the_sampler_s_prior_is_the_em_s(short_star):
    sim, shots = short_star
    tp = sim.header["transponders"]
    fit = locate_array(shots, tp, speed_intervals=0, prior_sd=np.full((3, 3), 0.2))
    post = ArrayLogPosterior(shots, fit)
    assert post.prior is not None
    u0 = post.u_em()
    du = np.zeros_like(u0)
    du[:9] = 0.1
    lp0, lp1 = post.log_prior(np.array([u0, u0 + du]))
    phi0 = (fit.enu - fit.start).ravel()
    phi1 = phi0 + 0.1
    expect = -0.5 * (phi1 @ phi1 - phi0 @ phi0) / 0.2**2
    assert lp1 - lp0 == pytest.approx(expect, rel=1e-9)
    free = ArrayLogPosterior(shots, locate_array(shots, tp, speed_intervals=0))
    assert free.prior is None
    # the Laplace covariance the proposal starts from includes the prior's precision
    assert np.all(np.diag(post.cov_geo)[:9] < 0.2**2)


def test_the_option_is_for_garpos_surveys_only(tmp_path, capsys):
    sim = simulate_gnssa(n_transponders=3, hours=0.3, rng=33)
    paths = sim.write(tmp_path / "n", "gnatss")
    assert main(["locate", str(paths["survey"]), "--out", str(tmp_path / "o"),
                 "--position-prior", "off"]) == 2
    err = capsys.readouterr().err
    assert "--position-prior: for GARPOS surveys only" in err and "Traceback" not in err
    garpos = sim.write(tmp_path / "g", "garpos")["survey"]
    assert main(["locate", str(garpos), "--out", str(tmp_path / "o2"),
                 "--position-prior", "off"]) == 0
    assert "Gaussian priors" not in capsys.readouterr().out
    assert main(["locate", str(garpos), "--out", str(tmp_path / "o3")]) == 0
    assert "Gaussian priors from the site file's sigmas" in capsys.readouterr().out


def test_write_garpos_writes_the_sigmas_given(tmp_path):
    sim = simulate_gnssa(n_transponders=3, hours=0.2, rng=34)
    site = write_garpos(tmp_path, sim.pings, sim.header, sigmas=(1.0, 0.0, 2.5))
    raw = read_garpos(site)
    np.testing.assert_array_equal(raw.header["position_sigmas"].to_numpy(),
                                  np.tile([1.0, 0.0, 2.5], (3, 1)))


def test_a_shift_without_a_prior_and_extreme_sds():
    """A dCentPos of inf: a shift with no prior; sds past 1e100 m none, below 1e-6 m refused."""
    free = np.zeros((3, 3), bool)
    G, P = _position_parameters(np.full((3, 3), 2.0), [np.inf, 0.0, 0.0], _tp(), IDS, free,
                                False)
    assert G.shape == (9, 10) and P[9, 9] == 0.0 and P[0, 0] == 0.25
    assert _position_parameters(np.full((3, 3), 1e300), None, _tp(), IDS, free, False)[1] is None
    with pytest.raises(InputError, match=r"prior_sd: \[1e-09\] m, below 1e-06 m"):
        _position_parameters(np.full((3, 3), 1e-9), None, _tp(), IDS, free, False)


def _site(folder, dpos, centre, shift=(0.6, -0.4, 0.3), **sim_kw):
    """A simulated GARPOS campaign, its geometry moved by ``shift``, with the sigmas given.

    ``dpos``: station -> three sigmas (others as written, 3/3/5 m); ``centre``: dCentPos's.
    """
    sim = simulate_gnssa(**sim_kw)
    true = sim.truth["transponders"][["east", "north", "up"]]
    site = write_garpos(folder, sim.pings, dict(sim.header, transponders=true - np.asarray(shift)),
                        sigmas=sim.settings["prior_sd"])
    text = site.read_text().splitlines()
    for i, ln in enumerate(text):
        key = ln.split("=")[0].strip()
        sig = centre if key == "dCentPos" else dpos.get(key[:-5]) if key.endswith("_dPos") else None
        if sig is not None:
            parts = ln.split("=")[1].split()
            text[i] = f" {key} = " + " ".join(parts[:3] + [f"{v:g}" for v in sig] + parts[6:])
    site.write_text("\n".join(text) + "\n")
    return read_garpos(site), true


def test_garpos_s_array_take_over_moves_a_held_transponder_with_the_shift(tmp_path):
    """M01's dPos sigmas 0, the others' 3 m, dCentPos 1 m: M01 moves with the shift (GARPOS)."""
    shift = np.array([0.6, -0.4, 0.3])
    raw, true = _site(tmp_path, {"M01": (0, 0, 0)}, (1, 1, 1), shift, n_transponders=3,
                      hours=1.0, rng=36)
    res = locate_array_survey(raw, gradients="off")
    fit = res.fits["array"]
    pos = res.summary["positions"]
    assert pos["mode"] == "each transponder and a common shift"
    assert pos["n_free"] == 9 and pos["n_fixed"] == 0 and pos["n_moved_by_shift_only"] == 3
    assert pos["prior"]["transponder_sd"]["M01"] == [0.0] * 3  # held: GARPOS's sigma of 0
    assert "3 coordinates whose sigma is 0 moved by the shift only (GARPOS's array " \
           "take-over)" in positions_line(res.summary)
    moved = fit.enu - fit.start
    np.testing.assert_allclose(moved[0], shift, atol=0.05)  # M01 held relative to the shift
    common = pos["common_shift"]  # GARPOS's dCentPos, reported beside the positions
    np.testing.assert_allclose([common[a]["mean"] for a in ("east", "north", "up")], moved[0],
                               atol=1e-9)  # M01 has no offset of its own: its move is the shift
    assert f"the common shift (dCentPos): east {common['east']['mean']:+.3f} +- " in \
        positions_line(res.summary)
    assert np.all(fit.sd[0] > 0.001)
    assert np.all(np.abs(fit.enu - true.to_numpy()) < 4 * fit.sd + 0.01)
    # the sampler's parameters are the EM's (8 of them here would miss the shift); nine of
    # them, but not the coordinates: not named as such
    post = ArrayLogPosterior(array_shots(raw), fit)
    assert post.F == 9 and post.prior is not None
    assert post.names[:2] == ("position_0", "position_1")


def test_a_held_east_offset_and_an_up_shift_count_right(tmp_path):
    raw, _ = _site(tmp_path, {"M01": (0, 3, 3)}, (0, 0, 1), n_transponders=3, hours=0.5,
                   rng=36)
    res = locate_array_survey(raw, gradients="off")
    pos = res.summary["positions"]
    assert pos["n_fixed"] == 1 and pos["n_coordinates"] == 9 and pos["n_free"] == 9
    assert "; 1 held at its prior position" in positions_line(res.summary)
    # every up has its own 5 m prior: the shift's up (1 m) is its prior's, and said so
    assert list(pos["common_shift"]) == ["up"] and pos["prior"]["mostly_prior"] == ["shift up"]
    res.write(tmp_path / "out")  # summary.json as JSON (no inf or NaN)


def test_held_coordinates_a_sharp_shift_moves_are_mostly_prior(tmp_path):
    """Every up held, dCentPos up 5 mm: the ups' sds are the shift's prior's, and said so."""
    raw, _ = _site(tmp_path, {f"M0{i}": (3, 3, 0) for i in (1, 2, 3)}, (0, 0, 0.005),
                   (0.6, -0.4, 0.0), n_transponders=3, hours=0.5, rng=36)
    res = locate_array_survey(raw, gradients="off", correlation="off")
    assert res.summary["positions"]["prior"]["mostly_prior"] == ["M01 up", "M02 up", "M03 up",
                                                                 "shift up"]


def test_the_proposal_scales_the_positions_prior_with_the_data_not_the_smoothing(tmp_path):
    """Sharp priors on every offset and on the shift, the smooth speed: the proposal had scaled
    the positions' prior with the smoothing scale, the pilot's ESS was 0.07 per draw and the
    sampler fell back to differential evolution; now 0.8."""
    from bayes_mpem.survey_in.array_sampling import sample_array

    raw, _ = _site(tmp_path, {f"M0{i}": (0.05,) * 3 for i in (1, 2, 3)}, (0.08, 0.08, 0.1),
                   (0.06, -0.04, 0.03), n_transponders=3, hours=1.0, rng=36)
    fit = locate_array_survey(raw, gradients="off", correlation="off").fits["array"]
    assert fit.model["smoothing"] is not None and fit.model["position_map"].shape == (9, 12)
    sp = sample_array(array_shots(raw), fit, min_ess=50, rng=1, progress=False, max_steps=300)
    d = sp.diagnostics
    assert d.get("fallback") is None and d["pilot"]["ess_per_draw"] > 0.3 and sp.converged
    # the file a user keeps says which prior the posterior assumed
    label = "Gaussian about the site file's positions on 12 of 12 position parameters (sds"
    assert d["position_prior"].startswith(label)
    assert sp.to_inference_data().attrs["position_prior"] == d["position_prior"]


def test_a_take_over_holding_the_horizontal_geometry_keeps_the_deep_gradient(tmp_path):
    """East and north offsets held, dCentPos horizontal: a circle cannot trade the deep term
    with the held geometry, as under a rigid shift."""
    raw, _ = _site(tmp_path, {f"M0{i}": (0, 0, 3) for i in (1, 2, 3, 4)}, (3, 3, 0),
                   (0.6, -0.4, 0.0), n_transponders=4, hours=1.2, rng=4, track="circle")
    res = locate_array_survey(raw, correlation="off")
    gate = res.summary["gradients"]["deep_gate"]
    assert gate["fit"] and gate["reason"].startswith("the horizontal geometry is held")


def test_a_site_file_sigma_too_sharp_to_fit_is_named(tmp_path, capsys):
    sim = simulate_gnssa(n_transponders=3, hours=0.3, rng=35)
    site = sim.write(tmp_path / "g", "garpos")["survey"]
    text = site.read_text().splitlines()
    row = next(i for i, ln in enumerate(text) if ln.lstrip().startswith("M02_dPos"))
    parts = text[row].split()
    parts[5] = "1e-9"  # sigma_E (key, '=', east, north, up, sigma_E, ...)
    text[row] = " " + " ".join(parts)
    site.write_text("\n".join(text) + "\n")
    assert main(["locate", str(site), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{site}: M02_dPos sigma_E 1e-09: a prior sd above 0 and below 1e-06 m" in err
    assert "Traceback" not in err and not (tmp_path / "o").exists()
    assert main(["locate", str(site), "--out", str(tmp_path / "o"), "--position-prior",
                 "off"]) == 0


def test_the_correlated_refit_weighs_the_prior_at_the_sigma_it_reports(short_star):
    """An unpenalised speed under correlated noise: the prior weighed at the EM's sigma (of
    independent replies) moved the positions 77 mm (2 sd) past the mode the reported sds
    describe; the refit now repeats its solve until sigma settles."""
    sim, shots = short_star
    true = sim.truth["transponders"][["east", "north", "up"]]
    tp = true + np.random.default_rng(0).normal(0.0, 0.03, (3, 3))
    kw = dict(correlation=(60.0, 0.5, 0.1), speed_intervals=0, gradients=False)
    free = locate_array(shots, tp, **kw)
    fit = locate_array(shots, tp, prior_sd=np.full((3, 3), 0.05), **kw)
    C = free.cov_model[:9, :9] * (fit.sigma / free.sigma) ** 2  # the data's, at fit's sigma
    A = np.linalg.inv(C) + np.eye(9) / 0.05**2
    mode = np.linalg.solve(A, np.linalg.solve(C, (free.enu - free.start).ravel()))
    np.testing.assert_allclose((fit.enu - fit.start).ravel(), mode, atol=0.002)
    assert fit.model["noise"]["refit_converged"]


def test_the_prior_check_flags_sigmas_that_understate_the_error(tmp_path):
    """Site positions drawn 6 m from the truth with sigmas of 2 m: the check says so."""
    from bayes_mpem.survey_in.array import _prior_check

    prior = np.diag(np.full(6, 1 / 4.0))  # sds of 2 m
    cov = np.diag(np.full(6, 0.01))
    assert _prior_check(np.full(6, 1.0), cov, prior)["p_value"] > 0.5
    bad = _prior_check(np.full(6, 6.0), cov, prior)
    assert bad["dof"] == 6 and bad["p_value"] < 1e-6
    assert _prior_check(np.ones(6), cov, None) is None
    sim = simulate_gnssa(n_transponders=3, hours=1.0, rng=37, prior_sd=(6.0, 6.0, 6.0))
    site = write_garpos(tmp_path / "bad", sim.pings, sim.header, sigmas=(2.0, 2.0, 2.0))
    res = locate_array_survey(read_garpos(site))
    check = res.summary["positions"]["prior"]["check"]
    assert check["p_value"] < 0.01 and check["dof"] == 9
    assert "CAUTION: the fit moved the positions farther from the site file's" in \
        positions_line(res.summary)
    good = write_garpos(tmp_path / "good", sim.pings, sim.header, sigmas=(6.0, 6.0, 6.0))
    res = locate_array_survey(read_garpos(good))
    assert res.summary["positions"]["prior"]["check"]["p_value"] > 0.01
    assert "CAUTION" not in positions_line(res.summary)


def test_auto_scales_up_sigmas_that_understate_the_moves_where_the_prior_matters(tmp_path):
    """Eight minutes of a star, positions drawn 6 m off, sigmas of 2 m.

    ``site`` keeps the sigmas and cautions; ``auto`` (the default) fits again with them
    scaled by the check's chi-squared over its degrees of freedom, and says so.
    """
    from bayes_mpem.survey_in.array import prior_scale

    sim = simulate_gnssa(n_transponders=3, hours=0.14, rng=5, depth=1500.0,
                         prior_sd=(6.0, 6.0, 6.0))
    site = write_garpos(tmp_path, sim.pings, sim.header, sigmas=(2.0, 2.0, 2.0))
    raw = read_garpos(site)
    true = sim.truth["transponders"][["east", "north", "up"]].to_numpy()
    as_given = locate_array_survey(raw, position_prior="site")
    k = prior_scale(as_given.fits["array"])
    assert k > 2.0
    assert "CAUTION" in positions_line(as_given.summary)
    auto = locate_array_survey(raw)
    rec = auto.summary["positions"]["prior"]
    assert rec["choice"] == "auto" and rec["scaled"]["sd_factor"] == pytest.approx(np.sqrt(k))
    assert rec["transponder_sd"]["M01"] == pytest.approx([2.0 * np.sqrt(k)] * 3)
    line = positions_line(auto.summary)
    assert f"sigmas scaled up {np.sqrt(k):.2f} times on 9 parameters" in line
    assert "the intervals carry the scale's uncertainty (variance factor " in line
    lo_k, hi_k = rec["scaled"]["scale_uncertainty"]["kappa_interval"]
    assert 1.0 <= lo_k < k < hi_k
    assert "(the sds here are the scaled ones)" in rec["kind"]
    from bayes_mpem.survey_in.array_sampling import _prior_label

    label = _prior_label(ArrayLogPosterior(array_shots(raw), auto.fits["array"]))
    assert f"its sigmas scaled up {np.sqrt(k):.4g} times" in label
    fit, fit0 = auto.fits["array"], as_given.fits["array"]
    assert np.all(fit.sd >= fit0.sd)
    assert np.max(np.abs((fit.enu - true) / fit.sd)) < np.max(np.abs((fit0.enu - true) / fit0.sd))
    # where the shots determine every parameter, nothing is scaled: the 1-hour campaign
    sim = simulate_gnssa(n_transponders=3, hours=1.0, rng=37, prior_sd=(6.0, 6.0, 6.0))
    site = write_garpos(tmp_path / "hour", sim.pings, sim.header, sigmas=(2.0, 2.0, 2.0))
    res = locate_array_survey(read_garpos(site))
    assert res.summary["positions"]["prior"]["scaled"] is None
    assert prior_scale(res.fits["array"]) == 1.0


def test_the_prior_scale_s_uncertainty_widens_what_the_prior_carries():
    """Linear-Gaussian campaigns: 8 coordinates the shots determine (3 cm), 4 they do not,
    every prior 6 m off while its sigma says 3 m. The scale is estimated from the 8 moves, as
    ``auto`` does; fixed at it, the 4 coordinates the prior carries covered 91.5 %; averaged
    over its posterior, 95 % (150 campaigns; 92.6 and 95.7 % over 400)."""
    from types import SimpleNamespace

    from bayes_mpem.survey_in.array import prior_scale_spread

    rng = np.random.default_rng(0)
    m = np.r_[np.full(8, 1 / 0.03**2), np.full(4, 1e-4)]
    P = np.eye(12) / 9.0
    hits = np.zeros(2)
    for _ in range(150):
        e = rng.normal(0.0, 6.0, 12)
        data = e + rng.normal(0.0, 1 / np.sqrt(m))
        k = max(np.sum(data[:8] ** 2) / 9.0 / 8, 1.0)
        C = np.linalg.inv(np.diag(m) + P / k)
        phi = C @ (m * data)
        fit = SimpleNamespace(model={"position_prior": P / k, "position_params_cov_model": C,
                                     "position_params": phi})
        extra, record = prior_scale_spread(fit, k)
        assert np.linalg.eigvalsh(extra).min() >= -1e-12
        assert np.abs(extra[:8, :8]).max() < 1e-3 * C[0, 0] + 1e-12  # the shots' own: as fitted
        for i, V in enumerate((C, C + extra)):
            hits[i] += np.sum(np.abs((phi - e)[8:]) < 1.96 * np.sqrt(np.diag(V)[8:]))
        assert record["kappa_interval"][0] < record["kappa_mean"] < record["kappa_interval"][1]
    cover = hits / 600
    assert cover[0] < 0.93 and 0.94 <= cover[1] <= 0.97, cover


def test_the_option_on_a_survey_located_one_at_a_time_says_garpos(tmp_path, capsys):
    from bayes_mpem.io.formats import sample_file

    src = sample_file("seagap/obsdata.inp")
    assert main(["locate", str(src), "--out", str(tmp_path / "o"), "--one-at-a-time",
                 "--position-prior", "off"]) == 2
    err = capsys.readouterr().err
    assert "--position-prior: for GARPOS surveys only" in err and "Traceback" not in err
