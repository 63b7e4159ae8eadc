"""Correlated noise of an array's replies: GARPOS's data covariance (docs/gnssa.md)."""

import dataclasses
import json

import numpy as np
import pytest

from bayes_mpem.cli import main
from bayes_mpem.exceptions import InputError
from bayes_mpem.io.formats import read_survey, sample_file
from bayes_mpem.survey_in.array_survey import locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa
from bayes_mpem.survey_in.noise import TAPER, Whitener, choose_correlation


def _dense(time, index, tau, share, white):
    dt = np.abs(time[:, None] - time[None, :])
    x = dt / (TAPER * tau)
    taper = np.clip(1 - x, 0, None) ** 4 * (4 * x + 1)
    same = index[:, None] == index[None, :]
    E = (1 - white) * np.exp(-dt / tau) * taper * (share + (1 - share) * same)
    np.fill_diagonal(E, 1.0)
    return E


@pytest.mark.parametrize("tau,share,white", [(60.0, 0.5, 0.0), (300.0, 0.0, 0.4),
                                             (30.0, 1.0, 0.7)])
def test_whitener_is_the_tapered_covariance(tau, share, white):
    gen = np.random.default_rng(3)
    time = np.repeat(np.cumsum(gen.uniform(5, 60, 120)), 3)[::-1].copy()  # 3 replies a shot
    index = np.concatenate([gen.permutation(4)[:3] for _ in range(120)])  # distinct
    w = Whitener(time, index, tau, share, white)
    E = _dense(time, index, tau, share, white)
    assert np.allclose(w.matrix(), E, atol=1e-12)
    assert w.logdet == pytest.approx(np.linalg.slogdet(E)[1], abs=1e-8)
    X = gen.normal(size=(time.size, 2))
    Xw = w.whiten(X)
    assert np.allclose(Xw.T @ Xw, X.T @ np.linalg.solve(E, X))


def test_taper_keeps_garpos_form_positive_definite():
    """Without a white share (GARPOS's own form) the tapered matrix still factors."""
    gen = np.random.default_rng(5)
    for _ in range(20):
        time = np.cumsum(gen.exponential(10.0, 300))
        index = gen.integers(0, 4, 300)
        E = _dense(time, index, gen.uniform(10, 600), gen.uniform(0, 1), 0.0)
        assert np.linalg.eigvalsh(E).min() > 0
        Whitener(time, index, 120.0, 0.5)  # banded Cholesky does not fail


def test_one_transponder_twice_at_once_is_refused_or_skipped():
    """GARPOS's form makes two replies of one transponder at one time one reply (singular)."""
    with pytest.raises(np.linalg.LinAlgError):
        Whitener([0.0, 0.0, 30.0], [1, 1, 2], 60.0, 0.5)
    (tau, _, white), table = choose_correlation(
        np.array([0.0, 0.0, 30.0, 60.0] * 50) + np.repeat(np.arange(50) * 90.0, 4),
        np.array([1, 1, 2, 3] * 50), np.random.default_rng(0).normal(size=200))
    assert all(row["white"] != 0.0 for row in table if row["correlation_s"] > 0)  # 0: singular


def test_independent_replies_are_the_identity():
    w = Whitener([3.0, 1.0, 2.0], [0, 1, 0], 0.0, 0.5)
    assert w.logdet == 0.0
    assert np.allclose(w.matrix(), np.eye(3))
    assert w.whiten(np.array([3.0, 1.0, 2.0])).tolist() == [1.0, 2.0, 3.0]  # time order


def _ou_every_20_s(gen, n, tau=120.0):
    """``(t, x)``: ``n`` times 20 s apart and a unit Ornstein-Uhlenbeck process of ``tau`` s."""
    t = np.arange(n) * 20.0
    a = np.exp(-20.0 / tau)
    ou = np.zeros(n)
    for i in range(1, n):
        ou[i] = a * ou[i - 1] + gen.normal(0, np.sqrt(1 - a * a))
    return t, ou


def test_choice_finds_an_ou_process_under_white_noise():
    gen = np.random.default_rng(2)
    t, ou = _ou_every_20_s(gen, 3000)
    r = ou + gen.normal(0, np.sqrt(0.6), t.size)  # white share 0.375
    (tau, _, white), table = choose_correlation(t, np.zeros(t.size, int), r)
    assert tau in (120.0, 180.0) and white in (0.3, 0.5)  # 120 s, 0.375 (the grid's nearest)
    (tau0, _, _), _ = choose_correlation(t, np.zeros(t.size, int), gen.normal(size=t.size))
    assert tau0 == 0.0
    assert max(row["log_likelihood"] for row in table) == 0.0


def test_independent_campaign_is_unchanged():
    """On the simulator's campaigns (independent in time) auto keeps independent replies."""
    raw = simulate_gnssa(hours=2, rng=4, speed_model="field").raw()
    auto = locate_array_survey(raw)
    off = locate_array_survey(raw, correlation="off")
    assert auto.summary["noise"]["correlation_s"] == 0.0
    assert auto.summary["noise"]["choice"] == "auto" and off.summary["noise"]["choice"] == "off"
    a, b = auto.fits["array"].centre(), off.fits["array"].centre()
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def _with_correlated_delay(raw, seed, sd=40e-6, tau=180.0):
    gen = np.random.default_rng(seed)
    p = raw.pings.copy()
    t = p["time"].to_numpy(float)
    delay = np.zeros(t.size)
    for k in p["transponder"].unique():
        sel = np.flatnonzero(p["transponder"].to_numpy() == k)
        sel = sel[np.argsort(t[sel])]
        x = gen.normal(0, sd)
        for i in sel:
            delay[i] = x
            x = x * np.exp(-20.0 / tau) + gen.normal(0, sd * np.sqrt(1 - np.exp(-40.0 / tau)))
    p["twtt"] = p["twtt"].to_numpy(float) + delay
    return dataclasses.replace(raw, pings=p)


def test_correlated_delay_is_found_and_widens_the_intervals():
    """The noise's choice alone: the gradient terms (fitted from 1 h by default) take up part
    of this 2-hour campaign's delay, and the correlation chosen with them is 60 s."""
    raw = _with_correlated_delay(simulate_gnssa(hours=2, rng=1, speed_model="field").raw(), 1)
    auto = locate_array_survey(raw, gradients="off")
    off = locate_array_survey(raw, correlation="off", gradients="off")
    nz = auto.summary["noise"]
    assert 120.0 <= nz["correlation_s"] <= 600.0 and nz["share"] == 0.0  # 180 s, per transponder
    assert "generalised least squares" in auto.summary["method"]
    sd_auto = np.sqrt(np.diag(auto.fits["array"].centre()[1]))
    sd_off = np.sqrt(np.diag(off.fits["array"].centre()[1]))
    assert np.all(sd_auto[:2] > 1.05 * sd_off[:2])


def test_seagap_residuals_are_correlated():
    """The real SeaGap survey: a correlation of minutes, and intervals about twice as wide.

    Without the gradient terms, as measured (docs/gnssa.md; ``auto`` fits them there).
    """
    raw = read_survey(sample_file("seagap/obsdata.inp"))
    auto = locate_array_survey(raw, gradients="off")
    off = locate_array_survey(raw, correlation="off", gradients="off")
    nz = auto.summary["noise"]
    assert nz["correlation_s"] >= 120.0 and not nz["at_grid_edge"]
    sd_auto = np.sqrt(np.diag(auto.fits["array"].centre()[1]))
    sd_off = np.sqrt(np.diag(off.fits["array"].centre()[1]))
    assert np.all(sd_auto > 1.4 * sd_off)
    assert np.all(np.abs(auto.fits["array"].centre()[0] - off.fits["array"].centre()[0])
                  < 2 * sd_auto)


@pytest.fixture(scope="module")
def garpos_campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("corr")
    assert main(["simulate", "--gnssa", "--hours", "1", "--seed", "2", "--out",
                 str(d / "camp")]) == 0
    return next((d / "camp").glob("*initcfg.ini"))


@pytest.mark.parametrize("value", ["-1", "abc", "60,2", "60,0.5,0.3,1", "60,0.5,1", "5000",
                                   "nan"])
def test_cli_refuses_a_bad_correlation(garpos_campaign, tmp_path, capsys, value):
    with pytest.raises(SystemExit) as exc:  # argparse's exit, status 2
        main(["locate", str(garpos_campaign), "--correlation", value, "--out",
              str(tmp_path / "o")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--correlation" in err and repr(value) in err
    assert not (tmp_path / "o").exists()


def test_cli_records_the_noise_and_refuses_misplaced_uses(garpos_campaign, tmp_path, capsys):
    assert main(["locate", str(garpos_campaign), "--correlation", "60,0.5",
                 "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "noise         correlated: mu_t 60 s, mu_mt 0.5, white 0 (given" in out
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["noise"]["correlation_s"] == 60.0 and s["noise"]["choice"] == "given"
    assert "noise         correlated" in (tmp_path / "o" / "solution.txt").read_text()
    assert main(["locate", str(garpos_campaign), "--correlation", "60,0.5,0.3", "--sample",
                 "--seed", "0", "--no-progress", "--out", str(tmp_path / "p")]) == 0
    capsys.readouterr()
    s = json.loads((tmp_path / "p" / "summary.json").read_text())
    assert s["noise"]["correlation_s"] == 60.0 and s["interval_method"] == "posterior"
    import xarray as xr

    tree = xr.open_datatree(tmp_path / "p" / "posterior_array.nc")
    assert tree.attrs["noise"].startswith("correlated: mu_t 60 s, mu_mt 0.5, white 0.3")
    deck = sample_file("obsrange/SIO_CC03.txt")
    assert main(["locate", str(deck), "--correlation", "off", "--out",
                 str(tmp_path / "q")]) == 2
    assert "--correlation: for array surveys only" in capsys.readouterr().err


def test_the_posterior_under_correlated_noise_is_the_gls_likelihood():
    """A true reply's density is its residual's given the earlier true replies' (Notes)."""
    from scipy.stats import multivariate_normal

    from bayes_mpem.survey_in.array_sampling import ArrayLogPosterior
    from bayes_mpem.survey_in.array_survey import array_shots

    raw = simulate_gnssa(hours=0.5, rng=2, shot_interval=30.0).raw()
    pings = raw.pings.sample(frac=1.0, random_state=0).reset_index(drop=True)  # not in time order
    raw = dataclasses.replace(raw, pings=pings)
    fit = locate_array_survey(raw, correlation=(60.0, 0.5, 0.3)).fits["array"]
    post = ArrayLogPosterior(array_shots(raw), fit)
    keep = np.flatnonzero(fit.p_true > 0.5)
    time = array_shots(raw).iloc[fit.rows]["time"].to_numpy(float)[keep]
    E = _dense(time, fit.index[keep], 60.0, 0.5, 0.3)
    gen = np.random.default_rng(0)
    u = post.u_em() + 0.3 * gen.normal(size=(3, post.ndim)) * (np.arange(post.ndim) < post.F)
    ld, _ = post.class_log_densities(u)
    _, _, _, sigma, w = post.split(u)
    r = post.t[keep] - post.predict(u)[:, keep]
    order = np.argsort(time, kind="stable")  # each reply given the earlier ones, densely
    L = np.linalg.cholesky(E[np.ix_(order, order)])
    for i in range(3):
        want = multivariate_normal.logpdf(r[i], cov=sigma[i] ** 2 * E)
        got = ld[i, keep] - np.log(w[i, fit.index[keep]])
        assert np.sum(got) == pytest.approx(want, rel=1e-9, abs=1e-6)
        z = np.linalg.solve(L, r[i, order])  # reply by reply: the conditional densities
        each = (-0.5 * (z / sigma[i]) ** 2 - np.log(sigma[i] * np.sqrt(2 * np.pi))
                - np.log(np.diag(L)))
        assert np.allclose(got[order], each, rtol=1e-9, atol=1e-8)
    # the data's precision of the proposal is the whitened one: J' E^-1 J
    data, _ = post._precisions
    J = post.model.jac(post.theta_em)[keep][:, :3 * post.K]
    assert np.allclose(data[:post.F, :post.F], J.T @ np.linalg.solve(E, J) / fit.sigma**2,
                       rtol=1e-8)


def test_the_posterior_samples_the_seagap_correlation():
    """On SeaGap (``mu_t`` 300 s) the posterior's sds are the GLS fit's, not independent ones.

    Without the gradient terms, as measured (``auto`` fits them there).
    """
    from bayes_mpem.survey_in.array_sampling import locate_array_survey_bayes

    raw = read_survey(sample_file("seagap/obsdata.inp"))
    res = locate_array_survey_bayes(raw, rng=0, progress=False, gradients="off")
    s = res.summary
    assert s["noise"]["correlation_s"] >= 120.0 and s["noise"]["choice"] == "auto"
    post, em = s["array_centre"]["enu"], s["array_centre"]["em"]["enu"]
    off = locate_array_survey(raw, correlation="off",
                              gradients="off").fits["array"].centre()[1]
    for j, a in enumerate(("east", "north", "up")):
        assert 0.8 < post[a]["sd"] / em[a]["sd"] < 1.15, a  # measured 0.89-0.95
        assert post[a]["sd"] > 1.3 * np.sqrt(off[j, j]), a  # measured 1.4-2.0
    assert res.posteriors["array"].converged
    noise = res.posteriors["array"].to_inference_data().attrs["noise"]
    assert noise.startswith(f"correlated: mu_t {s['noise']['correlation_s']:g} s")


def test_a_band_too_wide_is_not_tried():
    """A long time on a dense campaign would cost n b^2: the search stops before it."""
    t = np.arange(3000) * 1.0  # a reply a second
    with pytest.raises(ValueError, match="more than 500"):
        Whitener(t, np.zeros(3000, int), 300.0, 0.5)
    (tau, _, _), table = choose_correlation(t, np.zeros(3000, int),
                                            np.random.default_rng(0).normal(size=3000))
    assert [row["correlation_s"] for row in table][-1] <= 120.0  # 4 x 120 s = 480 replies


@pytest.mark.parametrize("value", ["60", "Auto", 60, (), (60, 0.5, 0.3, 1), (60, 0.5, 1.0),
                                   (60, 1.5), (-1,), (float("nan"),)])
def test_the_library_refuses_a_bad_correlation(value):
    raw = simulate_gnssa(hours=0.3, rng=1, shot_interval=30.0).raw()
    with pytest.raises(InputError, match="correlation: expected 'auto', 'off', None"):
        locate_array_survey(raw, correlation=value)


def test_garpos_form_with_a_full_share_is_refused_by_name():
    """``mu_mt`` 1 and no white share: replies to one interrogation would be one reply."""
    raw = simulate_gnssa(hours=0.3, rng=1, shot_interval=30.0).raw()
    with pytest.raises(InputError, match="one transponder heard twice, or a share of 1"):
        locate_array_survey(raw, correlation=(60.0, 1.0, 0.0))


def test_white_noise_keeps_independent_replies():
    """The best of the grid beats the independent model by chance: the margin keeps it."""
    gen = np.random.default_rng(7)
    t = np.sort(np.repeat(np.arange(400) * 20.0, 4))
    k = np.tile(np.arange(4), 400)
    picks = [choose_correlation(t, k, gen.normal(size=t.size))[0][0] for _ in range(20)]
    assert picks == [0.0] * 20


def test_the_command_line_reads_correlation_as_the_library_does():
    """``cli/options.py`` loads no numpy, so it parses ``--correlation`` itself: a twin."""
    from bayes_mpem.cli import options
    from bayes_mpem.survey_in.array import correlation_spec
    from bayes_mpem.survey_in.noise import CORRELATION_TIMES

    assert options.MAX_CORRELATION_S == CORRELATION_TIMES[-1]
    for text in ("60", "120,0", "300,0.5,0.4", "0", "1200,1,0.95"):
        assert options.correlation(text) == correlation_spec(
            tuple(float(v) for v in text.split(",")))
    assert options.correlation("off") == "off" and correlation_spec("off") is None


@pytest.mark.parametrize("peak", [0.0, 0.5, 0.95])
def test_the_refinement_climbs_to_the_best_white_share_without_trying_every_one(peak):
    """At the time chosen each share's white shares are climbed, not all evaluated.

    A synthetic evidence, unimodal in the white share with its peak at ``peak``, higher for
    the share 0 than for the scan's 0.5: the pair chosen is the best of all twelve, in fewer
    evaluations than the eleven others.
    """
    t, ou = _ou_every_20_s(np.random.default_rng(3), 600)

    def evidence(w):
        return (50.0 * (w.tau > 0) - 50.0 * (w.white - peak) ** 2 - 5.0 * w.share
                - 0.01 * abs(w.tau - 120.0))

    (tau, share, white), table = choose_correlation(t, np.zeros(t.size, int), ou,
                                                    evidence=evidence)
    assert (share, white) == (0.0, peak)
    refined = [(row["share"], row["white"]) for row in table if row["stage"] == "refine"]
    assert len(set(refined)) == len(refined)  # none twice
    assert len(refined) < 11 or peak == 0.95  # a peak at the far end: the whole climb
    assert all(row["correlation_s"] == tau for row in table if row["stage"] == "refine")
    (tau0, share0, white0), table = choose_correlation(t, np.zeros(t.size, int), ou,
                                                       evidence=evidence, refine=())
    assert tau0 > 0 and not any(row["stage"] == "refine" for row in table)  # the scan's stands
    (tau1, share1, white1), _ = choose_correlation(t, np.zeros(t.size, int), ou,
                                                   evidence=evidence, refine=(0.3,))
    assert tau1 > 0 and white1 in (0.3, white0)  # one white share: nothing to climb


def test_the_correlated_refit_runs_until_its_weights_settle(monkeypatch):
    """Rounds of weights and steps until no weight moves by 1 %; a warning where cut short."""
    from bayes_mpem.exceptions import LocateWarning
    from bayes_mpem.survey_in import array

    raw = _with_correlated_delay(simulate_gnssa(hours=2, rng=1, speed_model="field").raw(), 1)
    nz = locate_array_survey(raw).summary["noise"]
    assert nz["refit_converged"] and 2 <= nz["refit_rounds"] < array.REFIT_ROUNDS
    monkeypatch.setattr(array, "REFIT_ROUNDS", 1)  # the weights move on the first round
    with pytest.warns(LocateWarning, match="still moved by more than 1 % after 1 round$") as rec:
        nz = locate_array_survey(raw).summary["noise"]
    # the caller's line (locate_array_survey's), not a decorator's
    assert all(w.filename.endswith("array_survey.py") for w in rec)
    assert not nz["refit_converged"] and nz["refit_rounds"] == 1


def test_a_refit_whose_last_solve_stopped_short_is_not_called_converged(monkeypatch):
    """The refit's Gauss-Newton cut to one step (the EM's left alone): a warning, the record
    and ``converged`` say so; with its steps it converges."""
    from bayes_mpem.exceptions import LocateWarning
    from bayes_mpem.survey_in import array

    raw = _with_correlated_delay(simulate_gnssa(hours=2, rng=1, speed_model="field").raw(), 1)
    res = locate_array_survey(raw, correlation=(180.0, 0.0, 0.6))
    assert res.summary["noise"]["refit_gauss_newton_converged"] and res.fits["array"].converged
    solve = array.penalised_gauss_newton

    def cut(*args, normal=None, **kw):  # only the refit passes ``normal``
        return solve(*args, normal=normal, **kw, **({} if normal is None else {"max_steps": 1}))

    monkeypatch.setattr(array, "penalised_gauss_newton", cut)
    with pytest.warns(LocateWarning, match="refit under correlated noise ran out of steps"):
        res = locate_array_survey(raw, correlation=(180.0, 0.0, 0.6))
    assert not res.summary["noise"]["refit_gauss_newton_converged"]
    assert not res.fits["array"].converged


@pytest.mark.parametrize(("lam_g_moves", "rounds"), [((0.03, 0.03, 0.009), 3),
                                                     ((0.03, 0.02, 0.011, 0.0), 4),
                                                     ((0.03,) * 20, None)])
def test_the_refit_stops_on_the_1_percent_rule_of_either_weight(monkeypatch, lam_g_moves,
                                                                 rounds):
    """A set sequence of weights (the speed's fixed, the gradients' moving by the relative
    steps given, round after round): the refit stops at the first round after the first in
    which both weights moved by 1 % or less, and warns where ``REFIT_ROUNDS`` cuts it."""
    import pandas as pd

    from bayes_mpem.exceptions import LocateWarning
    from bayes_mpem.survey_in import array

    gen = np.random.default_rng(0)
    n = 60
    A = gen.standard_normal((n, 3))
    y = A @ [1.0, 2.0, 3.0] + 0.1 * gen.standard_normal(n)
    H, Hg = np.diag([0.0, 1.0, 1.0]), np.diag([1.0, 0.0, 0.0])
    steps = [1.0, *(1.0 + np.array(lam_g_moves)), 1.0]
    speed, gradients = iter([1.0] * 30), iter(10.0 * np.cumprod(steps))
    next(gradients)  # the EM's weight, given below

    def stub(pre, r, phi, Hp, sigma, lam, fixed):
        return next(gradients if Hp is Hg else speed)

    monkeypatch.setattr(array, "choose_smoothing", stub)
    sub = pd.DataFrame({"time": 10.0 * np.arange(n)})
    args = ((30.0, 0.5, 0.5), lambda th: A @ th - y, lambda th: A, np.zeros(3), np.ones(n),
            sub, np.zeros(n, int), H, Hg, 1.0, 10.0, 1.0)
    if rounds is None:
        with pytest.warns(LocateWarning, match=f"after {array.REFIT_ROUNDS} rounds"):
            _, record = array._correlated_refit(*args)
        assert record["refit_rounds"] == array.REFIT_ROUNDS and not record["refit_converged"]
    else:
        _, record = array._correlated_refit(*args)
        assert record["refit_rounds"] == rounds and record["refit_converged"]


def test_a_matrix_is_whitened_from_each_columns_first_row_to_the_same_numbers():
    """Columns zero before their knots (a spline's), of zeros, with a NaN, in any row order:
    the same numbers as LAPACK's whole banded solve."""
    from scipy.linalg.lapack import dtbtrs

    gen = np.random.default_rng(5)
    n = 400
    t = gen.uniform(0.0, 4000.0, n)
    w = Whitener(t, gen.integers(0, 4, n), 120.0, 0.5, 0.2)
    X = np.zeros((n, 40))
    X[:, :3] = gen.standard_normal((n, 3))
    order = np.argsort(t)
    for j in range(3, 38):  # non-zero over a window of time, as a B-spline's column
        rows = order[(j - 3) * 11:(j - 3) * 11 + 30]
        X[rows, j] = gen.standard_normal(rows.size)
    X[order[300], 38] = np.nan  # column 39 all zeros
    full, info = dtbtrs(w.ab, X[w.order], uplo="L")
    assert info == 0
    np.testing.assert_array_equal(w.whiten(X), full)
    assert np.isnan(full[300:, 38]).all() and not full[:, 39].any()
    np.testing.assert_array_equal(w.whiten(X[:, 5:6]), full[:, 5:6])
    dense = np.random.default_rng(6).standard_normal((n, 7))  # every column from row 0
    np.testing.assert_array_equal(w.whiten(dense), dtbtrs(w.ab, dense[w.order], uplo="L")[0])
    assert w.whiten(np.zeros((n, 0))).shape == (n, 0)  # LAPACK's solve is not called on it
