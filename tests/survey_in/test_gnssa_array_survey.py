"""Every multi-transponder survey is an array; the array's sound_speed record and solution.txt."""

import copy
import dataclasses
import json
import re
import shutil

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.cli import main
from bayes_mpem.exceptions import InputError, LocateWarning
from bayes_mpem.io.formats import read_survey, sample_file
from bayes_mpem.survey_in.array import locate_array
from bayes_mpem.survey_in.array_sampling import (
    MOVES_LABEL,
    ArrayLogPosterior,
    ConditionalProposal,
)
from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey, site_priors
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa
from bayes_mpem.survey_in.result import _solution_text, not_fitted_note
from bayes_mpem.survey_in.survey import is_array, locate_survey


@pytest.fixture(scope="module")
def seagap_short(tmp_path_factory):
    """SeaGap's sample, its first 600 shots (about 2.6 h, the four transponders)."""
    d = tmp_path_factory.mktemp("seagap")
    src = sample_file("seagap/obsdata.inp")
    for name in ("pxp-ini.inp", "tr-ant.inp", "ss_prof.inp"):
        shutil.copy(src.parent / name, d / name)
    lines = src.read_text().splitlines()[:600]
    (d / "obsdata.inp").write_text("\n".join(lines) + "\n")
    return d / "obsdata.inp"


@pytest.fixture(scope="module")
def seagap_raw(seagap_short):
    return read_survey(seagap_short, "seagap")


def test_seagap_is_an_array_unless_one_at_a_time(seagap_raw):
    assert is_array(seagap_raw) and not is_array(seagap_raw, one_at_a_time=True)
    arr = locate_survey(seagap_raw, speed_intervals=4).summary
    one = locate_survey(seagap_raw, one_at_a_time=True).summary
    assert "array_centre" in arr and "array_centre" not in one
    assert set(arr["transponders"]) == set(one["transponders"]) == {"1", "2", "3", "4"}
    # one sound speed shared by the array; each its own one at a time
    assert len({t["sound_speed"]["mean"] for t in arr["transponders"].values()}) == 1
    assert len({t["sound_speed"]["mean"] for t in one["transponders"].values()}) == 4
    assert arr["ssp"] == "ss_prof.inp" and arr["geometry"]["origin"] is None
    assert arr["transponders"]["1"]["lat"] is None
    prior = seagap_raw.header["transponders"]
    for tid, t in arr["transponders"].items():  # the array agrees with the prior to a metre
        moved = [t["enu"][c]["mean"] - prior.loc[tid, c] for c in ("east", "north", "up")]
        assert np.all(np.abs(moved) < 2.0), (tid, moved)
    centre = np.mean([[t["enu"][c]["mean"] for c in ("east", "north", "up")]
                      for t in arr["transponders"].values()], axis=0)
    np.testing.assert_allclose([arr["array_centre"]["enu"][c]["mean"]
                                for c in ("east", "north", "up")], centre, atol=1e-6)


def test_seagap_array_refuses_what_only_one_at_a_time_has(seagap_raw):
    with pytest.raises(InputError, match="fit_lag.*one transponder at a time"):
        locate_survey(seagap_raw, fit_lag=True)
    garpos = simulate_gnssa(n_transponders=3, hours=0.3, rng=2).raw()
    with pytest.raises(InputError, match="one_at_a_time"):
        locate_survey(garpos, one_at_a_time=True)


def test_locate_command_on_seagap(seagap_short, tmp_path, capsys):
    assert main(["locate", str(seagap_short), "--out", str(tmp_path / "a"),
                 "--speed-intervals", "4"]) == 0
    out = capsys.readouterr().out
    assert "array centre" in out
    assert (tmp_path / "a" / "solution.txt").is_file()
    per = json.loads((tmp_path / "a" / "summary.json").read_text())["residuals"]["per_transponder"]
    printed = dict(re.findall(r"transponder (\w+): .* rms ([\d.]+) ms", out))
    # each transponder's own rms, not the array's shared sigma (a review found the sigma)
    assert printed == {k: f"{v['rms_true']:.3g}" for k, v in per.items()}
    assert len(set(printed.values())) > 1
    assert main(["locate", str(seagap_short), "--out", str(tmp_path / "b"),
                 "--one-at-a-time"]) == 0
    assert not (tmp_path / "b" / "solution.txt").exists()
    site = simulate_gnssa(n_transponders=3, hours=0.3, rng=2).write(tmp_path / "g")["survey"]
    assert main(["locate", str(site), "--out", str(tmp_path / "d"), "--one-at-a-time"]) == 2
    assert "--one-at-a-time: for SeaGap" in capsys.readouterr().err


def test_seagap_array_posterior(seagap_short, seagap_raw, tmp_path, capsys):
    """The SeaGap array is sampled by the independence move: its proposal fits the posterior.

    The joint Laplace Student-t it replaced kept 0.1 % of its draws' importance here (the
    coupling of sigma with every other coordinate, and shares near 1), so the pilot handed
    over to differential evolution.
    """
    fit = locate_survey(seagap_raw, correlation="off").fits["array"]
    post = ArrayLogPosterior(array_shots(seagap_raw), fit)
    q = ConditionalProposal(post)
    np.testing.assert_allclose(q.W @ q.V, np.eye(q.ng), atol=1e-8)
    x = q.draw(2000, np.random.default_rng(1))
    lw = post(x) - q.log_density(x)
    w = np.exp(lw - lw.max())
    assert w.sum() ** 2 / (w ** 2).sum() > 0.8 * x.shape[0]
    assert main(["locate", str(seagap_short), "--out", str(tmp_path / "c"), "--sample",
                 "--min-ess", "300"]) == 0
    out = capsys.readouterr().out
    assert "centre sd east/north/up: posterior" in out
    s = json.loads((tmp_path / "c" / "summary.json").read_text())
    d = s["posterior"]["diagnostics"]
    assert d["moves"] == MOVES_LABEL and "fallback" not in d and d["converged"]
    assert (tmp_path / "c" / "posterior_array.nc").is_file()
    assert set(s["transponders"]) == {"1", "2", "3", "4"}


@pytest.fixture(scope="module")
def simulated():
    sim = simulate_gnssa(hours=1.0, rng=4, speed_model="field")
    return sim, locate_array_survey(sim.raw(), speed_intervals=4)


def test_sound_speed_record_has_a_unit_per_field(simulated):
    _, res = simulated
    ss = res.summary["sound_speed"]
    assert ss["unit"] == "m/s" and "scale" in ss["coefficients_unit"]
    assert ss["reference_m_s"] == pytest.approx(1500.0, abs=10.0)
    assert ss["interval_minutes"] == pytest.approx(res.summary["epoch"]["hours"] * 15.0,
                                                   rel=0.02)
    ser = ss["series"]
    assert len(ser["time_s"]) == len(ser["mean_m_s"]) == len(ser["sd_m_s"]) == 121
    assert np.mean(ser["mean_m_s"]) == pytest.approx(ss["mean"], abs=0.05)
    assert min(ser["sd_m_s"]) > 0.0
    straight = locate_array_survey(simulated[0].raw(), ssp="straight").summary["sound_speed"]
    assert straight["coefficients_unit"] == "m/s" and straight["reference_m_s"] is None


def test_solution_txt_holds_the_summary_to_the_mm(simulated, tmp_path):
    _, res = simulated
    paths = res.write(tmp_path)
    text = paths["solution"].read_text()
    s = json.loads(paths["summary"].read_text())
    assert text.startswith("bayes_mpem GNSS-A array solution")
    row = next(ln for ln in text.splitlines() if ln.startswith("array centre"))
    vals = [float(v) for v in row.split()[2:]]
    c = s["array_centre"]["enu"]
    np.testing.assert_allclose(vals, [c[k]["mean"] for k in ("east", "north", "up")]
                               + [c[k]["sd"] for k in ("east", "north", "up")], atol=6e-4)
    for tid in s["transponders"]:
        assert any(ln.startswith(tid) for ln in text.splitlines())
    assert f"{s['residuals']['rms_true']:.4f} ms" in text
    assert "SIM" in text and "cubic B-spline in time, 4 equal intervals" in text
    assert f"{s['sound_speed']['interval_minutes']:.1f} min each" in text


def test_solution_txt_names_the_smooth_spline_s_knots_once(tmp_path):
    sim = simulate_gnssa(n_transponders=3, hours=0.5, rng=4)
    text = locate_array_survey(sim.raw()).write(tmp_path)["solution"].read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("speed model"))
    assert "knots every" in line and "min each" not in line


@pytest.mark.parametrize(("edge", "says"), [
    (None, None), ("stiff", "stiffest smoothing tried"), ("rough", "try a shorter --knot-minutes"),
    ("flat", "not determined by the data")])
def test_solution_txt_says_where_the_speed_s_evidence_peaks(simulated, edge, says):
    summary = copy.deepcopy(simulated[1].summary)
    summary["sound_speed"]["smoothing"] = {"grid": {"edge": edge}}
    line = next(ln for ln in _solution_text(summary).splitlines()
                if ln.startswith("speed model"))
    assert (says is None and "evidence" not in line) or (says is not None and says in line)


def test_track_geometry_tells_a_circle_from_holding_station():
    """The shallow gradient's identifiability (docs/gnssa.md): spread over depth and azimuths."""
    g = {tr: locate_array_survey(simulate_gnssa(n_transponders=3, hours=1.0, track=tr,
                                                rng=2).raw()).summary["track"]
         for tr in ("circle", "station")}
    assert g["circle"]["spread_over_depth"] > 0.5 > 0.05 > g["station"]["spread_over_depth"]
    for t in g["circle"]["transponders"].values():
        assert t["azimuth_coverage_deg"] > 300 and t["max_incidence_deg"] > 45
    for t in g["station"]["transponders"].values():
        assert t["azimuth_coverage_deg"] < 30 and t["max_incidence_deg"] < 35


def test_locate_gradients_and_knot_options(tmp_path, capsys):
    sim = simulate_gnssa(n_transponders=3, hours=0.5, rng=21, speed_model="field")
    ini = sim.write(tmp_path / "camp", "garpos")["survey"]
    assert main(["locate", str(ini), "--out", str(tmp_path / "r"), "--knot-minutes", "10",
                 "--gradients", "on"]) == 0
    printed = capsys.readouterr().out
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    g = s["gradients"]
    assert g["fitted"] and g["choice"] == "on" and "gradients=on asked for" in g["reason"]
    assert s["sound_speed"]["smoothing"]["knot_minutes_asked"] == 10.0
    # the files read, beside the files written
    assert s["input_files"]["site"] == str(ini) and s["input_files"]["obs"].endswith("obs.csv")
    assert "summary.json" in s["files"] and "classified.csv" in s["files"]
    assert "gradients     fitted" in printed and "shallow east" in printed
    assert "gradients     fitted" in (tmp_path / "r" / "solution.txt").read_text()
    assert main(["locate", str(ini), "--out", str(tmp_path / "a")]) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["gradients"]["choice"] == "auto" and not s["gradients"]["fitted"]
    assert "need 1" in capsys.readouterr().out  # the reason, printed
    deck = sample_file("obsrange/SIO_CC03.txt")
    assert main(["locate", str(deck), "--out", str(tmp_path / "d"), "--gradients", "off"]) == 2
    assert "--gradients: for array surveys only" in capsys.readouterr().err


def test_seagap_array_on_the_sphere(seagap_raw):
    """SeaGap's frame is along the sphere: read flat, the array came out 0.6 m too deep."""
    from bayes_mpem.survey_in.survey import SEAGAP_TRANSDUCER_DEPTH

    sphere = locate_survey(seagap_raw, speed_intervals=2, gradients="off")
    up = seagap_raw.transducer_positions()
    surface = -0.5 * float(np.mean(up["tx"][2]) + np.mean(up["rx"][2])) - SEAGAP_TRANSDUCER_DEPTH
    flat = locate_array_survey(seagap_raw, ssp="survey", speed_intervals=2, gradients="off",
                               surface_depth=surface, earth="flat")
    assert "SeaGap's" in sphere.summary["geometry"]["earth"]
    for tid, t in sphere.summary["transponders"].items():
        deeper = flat.summary["transponders"][tid]["depth"]["mean"] - t["depth"]["mean"]
        assert 0.4 < deeper < 0.8, (tid, deeper)


def test_batch_passes_the_array_options(tmp_path):
    from bayes_mpem.batch import locate_raw
    from bayes_mpem.cli.batch import tasks_from_manifest
    from bayes_mpem.cli.parser import build_parser

    sim = simulate_gnssa(n_transponders=3, hours=0.4, rng=22, speed_model="field")
    ini = sim.write(tmp_path / "camp", "garpos")["survey"]
    manifest = tmp_path / "m.csv"
    manifest.write_text("name,survey,format,gradients,knot_minutes,flags\n"
                        f"a,{ini},garpos,on,10,reclassify\n")
    task, = tasks_from_manifest(manifest, "locate", build_parser().get_default("subparsers"))
    assert task.options["gradients"] == "on" and task.options["knot_minutes"] == 10.0
    assert task.options["flags"] == "reclassify"
    s = locate_raw(read_survey(ini, "garpos"), task.options).summary
    assert s["gradients"]["fitted"] and s["sound_speed"]["smoothing"]["knot_minutes_asked"] == 10
    assert s["file_flags"]["flags"] == "reclassify"


def _flagged_campaign(tmp_path):
    """A simulated GARPOS campaign whose obs.csv flags every 7th shot and ruins its time."""
    paths = simulate_gnssa(rng=5, hours=0.5, shot_interval=30.0).write(tmp_path / "g")
    obs = next((tmp_path / "g").glob("*obs.csv"))
    lines = obs.read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith(",SET"))
    cols = lines[head].split(",")
    tt, flag = cols.index("TT"), cols.index("flag")
    for i in range(head + 1, len(lines), 7):
        parts = lines[i].split(",")
        parts[tt], parts[flag] = f"{float(parts[tt]) + 0.05:.7f}", "True"  # 37 m too long
        lines[i] = ",".join(parts)
    obs.write_text("\n".join(lines) + "\n")
    return paths["survey"]


def test_flagged_shots_are_left_out_unless_reclassified(tmp_path, capsys):
    config = _flagged_campaign(tmp_path)
    raw = read_survey(config, "garpos")
    flagged = raw.pings["file_flag"].to_numpy(bool)
    assert 20 < flagged.sum() < 60
    honoured = locate_array_survey(raw)
    cls = honoured.classified.set_index("line").loc[raw.pings["line"]]
    assert cls["p_true"][flagged].isna().all() and cls["p_true"][~flagged].notna().all()
    assert cls["reason"][flagged].str.contains("flagged in the file").all()
    assert honoured.summary["file_flags"] == {"n_flagged": int(flagged.sum()), "flags": "honour",
                                              "honoured": True, "n_flagged_called_spurious": 0}
    k = int(flagged.sum())  # read, not fitted: counted where the true and spurious are
    assert not_fitted_note(honoured.summary) == (f"{k} shots not fitted: {k} flagged in the "
                                                 "file (reasons in classified.csv)")
    assert f"              {k} shots not fitted" in _solution_text(honoured.summary)
    fit = honoured.fits["array"]
    assert not np.isin(fit.rows, np.flatnonzero(flagged)).any()
    # the same as the campaign without those shots: the flags decide, not the EM
    kept = locate_array(array_shots(raw)[~flagged].reset_index(drop=True),
                        raw.header["transponders"], **_same_model(fit),
                        **dict(zip(("prior_sd", "centre_sd"), site_priors(raw.header),
                                   strict=True)))
    np.testing.assert_allclose(fit.enu, kept.enu, rtol=0, atol=1e-6)
    re = locate_array_survey(raw, flags="reclassify")
    assert not_fitted_note(re.summary) is None
    p = re.classified.set_index("line").loc[raw.pings["line"], "p_true"].to_numpy()
    assert np.isfinite(p).all() and (p[flagged] < 0.5).all()  # 37 m off: spurious
    assert re.summary["file_flags"]["n_flagged_called_spurious"] == flagged.sum()
    with pytest.raises(InputError, match="flags: expected"):
        locate_array_survey(raw, flags="ignore")
    one = raw.pings["transponder"].astype(str) == "M01"  # every shot of M01 flagged
    raw.pings.loc[one, "file_flag"] = True
    with pytest.warns(LocateWarning, match="1 transponder not located .M01: 0 shots not "
                                           "flagged"):
        whole = locate_array_survey(raw).summary
    skipped = whole["skipped_transponders"]
    assert list(skipped) == ["M01"] and "0 shots not flagged" in skipped["M01"]
    # counted as classified.csv gives the reason: not located first (a review)
    n1 = int(one.sum())
    assert whole["not_fitted"]["transponder_not_located"] == n1
    assert f", {n1} of a transponder not located" in not_fitted_note(whole)
    assert main(["locate", str(config), "--out", str(tmp_path / "r"),
                 "--flags", "reclassify"]) == 0
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["file_flags"]["flags"] == "reclassify" and not s["file_flags"]["honoured"]
    capsys.readouterr()
    obs = tmp_path / "o.txt"
    obs.write_text("1 M01 2.5 0 0 -5\n")
    assert main(["locate", str(obs), "--format", "obsrange-sio", "--out", str(tmp_path / "x"),
                 "--flags", "honour"]) == 2
    assert "--flags: for array surveys only" in capsys.readouterr().err


def _same_model(fit):
    m = fit.model
    return {"profile": m["profile"], "surface_depth": m["surface_depth"],
            "earth_radius": m["earth_radius"], "along_sphere": m["along_sphere"],
            "gradients": bool(m["gradients"]),
            "time_range": m["time_range"],
            "correlation": None if not m["noise"] or not m["noise"]["correlation_s"] else
            (m["noise"]["correlation_s"], m["noise"]["share"], m["noise"]["white"])}


def test_a_seagap_survey_of_one_transponder_takes_the_array_defaults(tmp_path, capsys):
    """SeaGap's format is read as an array: with one transponder its defaults must not break.

    Before: ``locate`` refused ``speed_intervals None`` and ``locate --sample`` raised a
    TypeError (``gradients`` passed to the one-transponder sampler).
    """
    src = sample_file("seagap/obsdata.inp")
    for name in ("tr-ant.inp", "ss_prof.inp"):
        shutil.copy(src.parent / name, tmp_path / name)
    (tmp_path / "pxp-ini.inp").write_text((src.parent / "pxp-ini.inp").read_text()
                                          .splitlines()[0] + "\n")
    lines = [ln for ln in src.read_text().splitlines() if ln.split()[0] == "1"][:150]
    (tmp_path / "obsdata.inp").write_text("\n".join(lines) + "\n")
    survey = str(tmp_path / "obsdata.inp")
    assert main(["locate", survey, "--out", str(tmp_path / "a")]) == 0
    assert main(["locate", survey, "--sample", "--no-progress", "--min-ess", "200",
                 "--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "b" / "posterior_1.nc").is_file()
    capsys.readouterr()
    assert main(["locate", survey, "--correlation", "60", "--out", str(tmp_path / "c")]) == 2
    assert "correlation: for array surveys only" in capsys.readouterr().err


def test_shots_spanning_years_are_refused_naming_the_jump():
    """Two time scales mixed in one file (half the times in J2000 seconds) are refused, the
    jump and its lines named; two sessions 20 days apart are one campaign."""
    raw = simulate_gnssa(n_transponders=3, hours=0.5, rng=4).raw()
    p = raw.pings.copy()
    p["line"] = np.arange(2, len(p) + 2)
    half = p["t_tx"] > p["t_tx"].median()
    for days, ok in ((20.0, True), (8766.0, False)):
        q = p.copy()
        for c in ("t_tx", "t_rx", "time"):
            q.loc[half, c] = q.loc[half, c] + days * 86400.0
        shifted = dataclasses.replace(raw, pings=q)
        if ok:
            assert len(array_shots(shifted)) == len(q)  # two sessions 20 days apart
            continue
        with pytest.raises(InputError, match="the shots span 8,76[67] days") as err:
            array_shots(shifted)
        last = int(q.loc[~half, "line"].iloc[-1])
        assert f"between line {last} " in str(err.value) and "time scales mixed" in str(err.value)


def test_a_seagap_survey_hearing_one_transponder_locates_it_and_lists_the_others():
    """pxp-ini.inp lists four; the one heard is located, the others listed as not located."""
    raw = read_survey(sample_file("seagap/obsdata.inp"))
    first = raw.pings.iloc[:200]
    one = dataclasses.replace(raw, pings=first[first["transponder"].astype(str) == "1"])
    for kw in ({}, {"one_at_a_time": True}):
        res = locate_survey(one, **kw)
        assert list(res.summary["transponders"]) == ["1"]
        assert res.summary["skipped_transponders"] == dict.fromkeys(
            ("2", "3", "4"), "no replies in the survey")


def test_shots_from_one_place_say_how_many_replies_were_skipped_and_why():
    """Most replies skipped can leave shots from one place: the refusal says so."""
    raw = simulate_gnssa(n_transponders=3, hours=0.5, rng=4).raw()
    p = raw.pings.iloc[:5].copy()
    for c in ("e_tx", "n_tx", "e_rx", "n_rx"):
        p[c] = p[c].iloc[0]
    skipped = pd.DataFrame([(10, "a", "no position at the transmit time 1.5"),
                            (11, "b", "no position at the transmit time 2.5"),
                            (12, "c", "column 3: got 'x'")], columns=["line", "text", "reason"])
    one = dataclasses.replace(raw, pings=p, skipped=skipped)
    with pytest.raises(InputError, match=r"within 1 m of one place.*; 5 shots read, 3 lines or "
                       r"replies skipped: 2 lines: no position at the transmit time 1.5 \(first "
                       r"line 10\); 1 line: column 3: got 'x' \(line 12\)$"):
        array_shots(one)
    with pytest.raises(InputError, match=r"track over the array\)$"):  # nothing skipped
        array_shots(dataclasses.replace(one, skipped=skipped.iloc[:0]))


def test_locate_survey_gives_an_array_the_smooth_speed_by_default(seagap_raw):
    """In Python as on the command line: an array's sound speed is the smooth spline unless
    ``speed_intervals`` is given."""
    smooth = locate_survey(seagap_raw, correlation="off").fits["array"]
    one = locate_survey(seagap_raw, correlation="off", speed_intervals=0).fits["array"]
    assert smooth.model["smoothing"] is not None and one.model["smoothing"] is None
    assert smooth.model["speed_intervals"] > 0 and one.model["speed_intervals"] == 0


def test_the_defaults_fit_the_gradients_on_the_whole_seagap_survey():
    """The shipped survey's track spreads over 0.16 of the depth, above the gate (0.1)."""
    from bayes_mpem.survey_in.array_survey import gradient_gate

    raw = read_survey(sample_file("seagap/obsdata.inp"))
    fit, why = gradient_gate(array_shots(raw), raw.header["transponders"])
    assert fit and "spreads over 0.16 of the depth" in why, why


def test_a_fit_above_the_transducer_is_refused_as_the_mirror_image():
    """Prior positions given in km: the ranges' mirror image in the transducer's level fits
    them as well, 1,500 m above the sea, with sds of cm (found by a review)."""
    raw = simulate_gnssa(hours=1, rng=3).raw()
    header = copy.deepcopy(raw.header)
    header["transponders"][["east", "north", "up"]] /= 1000.0
    with pytest.raises(InputError, match=r"transponder M0\d was located [\d,]+ m above the "
                                         r"transducer .* mirror image .* prior up -1\.\d+ m"):
        locate_array_survey(dataclasses.replace(raw, header=header))


def test_garpos_times_restarted_at_midnight_are_warned_of():
    """A campaign across midnight whose ST restarts at 0 reads as spanning 24 h (a review)."""
    import warnings

    from bayes_mpem.exceptions import LocateWarning
    from bayes_mpem.survey_in.array_survey import _check_midnight

    raw = simulate_gnssa(hours=1, rng=3).raw()
    late = dataclasses.replace(raw, pings=raw.pings.assign(time=raw.pings["time"] + 84600.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _check_midnight(raw)  # 0-1 h of the day: nothing said
        _check_midnight(late)  # 23:30-24:00 and on past 86,400 s: GARPOS's own way
    wrapped = dataclasses.replace(raw, pings=raw.pings.assign(
        time=(raw.pings["time"] + 84600.0) % 86400.0))
    with pytest.warns(LocateWarning, match=r"jump by 23\.0 h, from 1780\.0 s \(line \d+\) to "
                                           r"84600\.0 s .* restart at 0 after midnight"):
        _check_midnight(wrapped)
