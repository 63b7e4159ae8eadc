"""The survey-in report: drift, azimuth, TAT, sound speed and depth against OBSrange; lag check."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.cli import main
from bayes_mpem.io.formats import read_survey
from bayes_mpem.survey_in.drift import drift_from_draws, drift_from_fit
from bayes_mpem.survey_in.survey import locate_survey

DATA = Path(__file__).resolve().parents[2] / "data" / "obsrange"


def _obsrange_solution():
    """OBSrange's published CC03 bootstrap solution: {name: (value, 2 sigma)}."""
    out = {}
    for line in (DATA / "CC03_obsrange_solution.txt").read_text().splitlines():
        m = re.match(r"^\s*([A-Za-z. ]+):\s+(-?[\d.]+)\s+\S*\s*±\s*([\d.]+)", line)
        if m:
            out[m.group(1).strip()] = (float(m.group(2)), float(m.group(3)))
    return out


def test_cc03_report_agrees_with_obsrange_within_its_2_sigma(tmp_path, capsys):
    """Drift, azimuth, sound speed, depth and depth change of CC03; TAT as OBSrange fixes it."""
    sol = _obsrange_solution()
    assert main(["locate", str(DATA / "SIO_CC03.txt"), "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    t = json.loads((tmp_path / "summary.json").read_text())["transponders"]["CC03"]
    checks = {"Drift": t["drift"]["mean"], "Drift Az": t["azimuth"]["mean"],
              "Water Vel.": t["sound_speed"]["mean"], "Depth": -t["depth"]["mean"],
              "dz": -t["depth_change"]["mean"]}  # OBSrange's dz is the rise
    for name, ours in checks.items():
        value, two_sigma = sol[name]
        assert abs(ours - value) < two_sigma, (name, ours, value, two_sigma)
    # OBSrange fixes the turn-around time at 13 ms (its inversion parameters); so do we
    assert t["tat"] == {"mean": 0.013, "sd": 0.0, "fitted": False}
    # our intervals are of OBSrange's size (its 2 sigma against our 95 %)
    for key, name in (("drift", "Drift"), ("azimuth", "Drift Az"), ("depth", "Depth")):
        lo, hi = t[key]["interval"]
        assert 0.5 < (hi - lo) / (2 * sol[name][1]) < 2.0, key
    assert "drift 90.27 [" in printed and "azimuth 8.5 [" in printed and "TAT 13.00" in printed


def test_classified_has_every_pings_residual(tmp_path):
    raw = read_survey(DATA / "SIO_CC03.txt")
    res = locate_survey(raw)
    cls = res.classified
    pinged = cls[cls["label"] != "skipped"]
    assert len(pinged) == 88 and pinged["residual_ms"].notna().all()
    fit = res.fits["CC03"]
    true = pinged[pinged["label"] == "true"]
    assert np.sqrt(np.mean(true["residual_ms"] ** 2)) == pytest.approx(1e3 * fit.sigma, rel=0.05)
    assert (pinged.loc[pinged["label"] == "spurious", "residual_ms"].abs() > 5).all()
    az = pinged["azimuth_deg"].to_numpy()
    assert az.min() >= 0 and az.max() < 360 and np.ptp(az) > 300  # a circle around it
    res.write(tmp_path)
    back = pd.read_csv(tmp_path / "classified.csv", keep_default_na=False)
    assert list(back.columns[:7]) == ["line", "transponder", "twtt", "p_true", "p_spurious",
                                      "label", "reason"]


def test_drift_interval_is_the_delta_method():
    """The Wald sd of drift and azimuth against Monte Carlo draws of the same Gaussian."""
    gen = np.random.default_rng(0)
    mean = np.array([13.0, 89.0, 4739.0])
    cov = np.array([[0.3, 0.1, 0.0], [0.1, 0.6, 0.2], [0.0, 0.2, 2.4]])
    draws = gen.multivariate_normal(mean, cov, 200_000)
    wald = drift_from_fit(*mean, cov, 4750.0)
    mc = drift_from_draws(*draws.T, 4750.0)
    for key in ("drift", "azimuth", "depth_change"):
        assert wald[key]["sd"] == pytest.approx(mc[key]["sd"], rel=0.02), key
        assert wald[key]["mean"] == pytest.approx(mc[key]["mean"], abs=0.01 * mc[key]["sd"] + 1e-3)
    assert wald["depth_change"]["mean"] == pytest.approx(-11.0)


def test_azimuth_draws_across_north_stay_together():
    gen = np.random.default_rng(1)
    e = gen.normal(0.0, 1.0, 4000)
    d = drift_from_draws(e, np.full(4000, 20.0), np.zeros(4000))
    lo, hi = d["azimuth"]["interval"]
    assert 9.0 < hi - lo < 13.0  # 2 x 1.96 x atan(1 / 20); 360 if the draws split at north
    assert d["azimuth"]["mean"] < 1.0 or d["azimuth"]["mean"] > 359.0


@pytest.mark.parametrize(("name", "recommended"), [("WHOI_S05.txt", True),
                                                   ("SIO_CC03.txt", False),
                                                   ("SIO_EC03.txt", False)])
def test_the_lag_check_recommends_a_lag_on_the_whoi_log_only(name, recommended):
    raw = read_survey(DATA / name)
    lc = locate_survey(raw, lag_check=True).summary["transponders"][raw.header["site"]][
        "lag_check"]
    assert lc["recommended"] is recommended
    if recommended:  # docs/measured-data.md: 5.37 s, rms 4.56 -> 1.11 ms
        assert 4.5 < lc["lag"] < 6.5 and lc["rms_ms_with"] < 0.4 * lc["rms_ms_without"]
        assert lc["gain"] > 100 and lc["gain"] > 5 * lc["gain_se"]


def test_locate_command_prints_the_lag_advice(tmp_path, capsys):
    assert main(["locate", str(DATA / "WHOI_S05.txt"), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "lag check: a lag of 5.37" in out and "re-run with --fit-lag" in out
    assert main(["locate", str(DATA / "WHOI_S05.txt"), "--out", str(tmp_path),
                 "--no-lag-check"]) == 0
    assert "lag check" not in capsys.readouterr().out
    s = json.loads((tmp_path / "summary.json").read_text())
    assert "lag_check" not in s["transponders"]["S05"]
