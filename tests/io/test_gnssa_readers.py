"""GARPOS and GNATSS readers: written by our simulator, read back; every line accounted for."""

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.formats import read_survey, sample_file, sniff_format
from bayes_mpem.io.garpos import read_garpos, write_garpos
from bayes_mpem.io.geodesy import atd_offset_enu, ecef_to_enu, enu_to_ecef, geodetic_to_ecef
from bayes_mpem.io.gnatss import read_gnatss, write_gnatss
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa


@pytest.fixture(scope="module")
def sim():
    return simulate_gnssa(n_transponders=3, hours=0.5, rng=4, origin=(38.0, 143.0, 25.0))


@pytest.fixture()
def garpos(sim, tmp_path):
    return write_garpos(tmp_path / "garpos", sim.pings, sim.header)


@pytest.fixture()
def gnatss(sim, tmp_path):
    return write_gnatss(tmp_path / "gnatss", sim.pings, sim.header, transducer_delay=0.13)


def _transducers(pings, header):
    out = {}
    for end in ("tx", "rx"):
        d = atd_offset_enu(*header["atd_offset"], pings[f"head_{end}"], pings[f"pitch_{end}"],
                           pings[f"roll_{end}"])
        out[end] = [pings[f"{c}_{end}"].to_numpy() + v for c, v in zip("enu", d, strict=True)]
    return out


def test_garpos_round_trip(sim, garpos):
    raw = read_garpos(garpos)
    p = raw.pings
    assert raw.format == "garpos" and len(p) == len(sim.pings) and raw.skipped.empty
    assert list(p["transponder"]) == list(sim.pings["transponder"])  # ids exact
    np.testing.assert_allclose(p["twtt"], sim.pings["twtt"], atol=1e-7)
    for c in ("e_tx", "n_tx", "u_tx", "e_rx", "u_rx"):
        np.testing.assert_allclose(p[c], sim.pings[c], atol=1e-5)
    np.testing.assert_allclose(p["head_rx"], sim.pings["head_rx"], atol=1e-3)
    h = raw.header
    assert (h["lat"], h["lon"], h["height"]) == (38.0, 143.0, 25.0)
    np.testing.assert_allclose(h["transponders"], sim.header["transponders"], atol=1e-4)
    np.testing.assert_allclose(h["atd_offset"], [1.5, -0.8, 12.0])
    np.testing.assert_allclose(h["ss_prof"]["sound_speed"], sim.header["ss_prof"]["sound_speed"],
                               atol=1e-4)
    # the transducer: antenna + offset turned by the attitude
    pos, ref = raw.transducer_positions(), _transducers(sim.pings, sim.header)
    for end in ("tx", "rx"):
        np.testing.assert_allclose(np.array(pos[end]), np.array(ref[end]), atol=1e-3)
    # every line: a comment, the header, or a shot
    n_lines = len(Path(raw.header["files"]["obs"]).read_text().splitlines())
    assert n_lines == 2 + len(p) and p["line"].min() == 3


def test_gnatss_round_trip(sim, gnatss):
    raw = read_gnatss(gnatss)
    p, s = raw.pings, sim.pings
    assert raw.format == "gnatss" and len(p) == len(s)
    order = np.lexsort((s["transponder"], s["t_tx"]))
    s = s.iloc[order].reset_index(drop=True)
    p = p.sort_values(["t_tx", "transponder"]).reset_index(drop=True)
    assert list(p["transponder"]) == list(s["transponder"])
    np.testing.assert_allclose(p["twtt"], s["twtt"], atol=1e-6)  # microseconds in the file
    np.testing.assert_allclose(p["time"], s["time"], atol=1e-6)  # transducer delay undone
    ref = _transducers(s, sim.header)
    for end in ("tx", "rx"):
        for k, c in enumerate("enu"):
            np.testing.assert_allclose(p[f"{c}_{end}"], ref[end][k], atol=2e-3)
    h = raw.header
    np.testing.assert_allclose(h["transponders"][["east", "north", "up"]],
                               sim.header["transponders"], atol=1e-6)
    assert h["surface_depth"] == pytest.approx(0.0, abs=1e-9)  # geoid = the sea surface at +25 m
    # missing replies are zeros, not shots: lines with no reply at all are skipped
    tt = Path(gnatss).with_name("pxp_tt").read_text().splitlines()
    assert set(p["line"]) | set(raw.skipped["line"]) == set(range(1, len(tt) + 1))


def test_the_formats_are_recognised(garpos, gnatss):
    assert sniff_format(garpos) == "garpos" and sniff_format(gnatss) == "gnatss"
    for name, fmt in (("obsrange/SIO_CC03.txt", "obsrange-sio"),
                      ("obsrange/WHOI_S05.txt", "obsrange-whoi"), ("seagap/obsdata.inp", "seagap")):
        assert sniff_format(sample_file(name)) == fmt
    assert read_survey(garpos).format == "garpos"
    with pytest.raises(InputError, match="not a survey format"):
        sniff_format(sample_file("obsrange/CC03_obsrange_solution.txt"))


def test_garpos_paths_from_the_working_folder_or_beside_the_site(garpos, tmp_path,
                                                                 monkeypatch):
    """A relative path is taken from the working folder or beside the site file; two
    different files of that name are refused (else one campaign's site file could be fitted
    to another's data)."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    raw = read_garpos(garpos)  # found beside the site file
    assert Path(raw.header["files"]["obs"]).parent == garpos.parent
    obs = garpos.with_name(garpos.name.replace("initcfg.ini", "obs.csv"))
    text = obs.read_text().splitlines()
    (work / obs.name).symlink_to(obs)  # the same file in both places: fine
    assert len(read_garpos(garpos).pings) == len(raw.pings)
    (work / obs.name).unlink()
    (work / obs.name).write_text("\n".join(text[:12]) + "\n")  # another campaign's file
    with pytest.raises(InputError, match="names two different files") as err:
        read_garpos(garpos)
    assert str(work / obs.name) in str(err.value) and str(obs) in str(err.value)
    assert "datacsv" in str(err.value)  # the site file's line and key
    os.replace(work / obs.name, obs)  # only in the site's folder: read there
    assert len(read_garpos(garpos).pings) == 10
    os.replace(obs, work / obs.name)  # only in the working folder (GARPOS's own way): read
    assert Path(read_garpos(garpos).header["files"]["obs"]) == work / obs.name
    os.remove(garpos.with_name(garpos.name.replace("initcfg.ini", "svp.csv")))
    with pytest.raises(FileNotFoundError, match="svp.csv' not found"):
        read_garpos(garpos)


def test_gnatss_paths_from_another_campaign_s_folder_are_refused(gnatss, tmp_path,
                                                                  monkeypatch):
    other = tmp_path / "other"
    write_gnatss(other, *_other_campaign())
    monkeypatch.chdir(other)  # its files have the same names as this campaign's
    with pytest.raises(InputError, match="different files") as err:
        read_gnatss(gnatss)
    assert "config.yaml" in str(err.value)
    text = gnatss.read_text()
    gnatss.write_text(text.replace("path: pxp_tt", "path: pxp_t*"))  # a pattern
    with pytest.raises(InputError, match="'pxp_t\\*' matches different files"):
        read_gnatss(gnatss)
    monkeypatch.chdir(tmp_path)
    raw = read_gnatss(gnatss)
    assert all(Path(f).parent == gnatss.parent for f in raw.header["files"]["travel_times"])
    gnatss.write_text(text)
    monkeypatch.chdir(gnatss.parent)  # the same files from both places
    assert len(read_gnatss(gnatss).pings) == len(raw.pings)


def _other_campaign():
    o = simulate_gnssa(n_transponders=3, hours=0.3, rng=99)
    return o.pings, o.header


def _edit_obs(garpos, line, field, value):
    obs = garpos.with_name(garpos.name.replace("initcfg.ini", "obs.csv"))
    lines = obs.read_text().splitlines()
    parts = lines[line - 1].split(",")
    parts[field] = value
    lines[line - 1] = ",".join(parts)
    obs.write_text("\n".join(lines) + "\n")
    return obs


@pytest.mark.parametrize(("field", "value", "reason"), [
    (4, "abc", "column 5 (TT: expected a number in (0, 60], got 'abc')"),
    (4, "-0.2", "column 5 (TT: expected a number in (0, 60], got '-0.2')"),
    (4, "nan", "TT: expected a number"),
    (14, "95", "column 15 (pitch0: expected a number in [-90, 90], got '95')"),
    (16, "0.5", "column 17 (RT): expected 0-120 s after ST"),
    (3, "M99", "column 4 (MT): transponder 'M99' is not one of the site's Stations"),
    (3, "M00", "a reply GARPOS could not assign"),
    (8, "maybe", "flag: expected True or False, got 'maybe'"),
])
def test_garpos_malformed_shots_are_skipped_with_the_reason(garpos, field, value, reason):
    obs = _edit_obs(garpos, 7, field, value)
    raw = read_garpos(garpos)
    (row,) = raw.skipped.itertuples()
    assert row.line == 7 and reason in row.reason
    assert 7 not in set(raw.pings["line"])
    if value != "M00":  # a reply nobody could assign is no error, even strict
        with pytest.raises(InputError, match=rf"{obs.name} line 7"):
            read_garpos(garpos, strict=True)


def test_garpos_wrong_width_and_missing_column(garpos):
    obs = garpos.with_name(garpos.name.replace("initcfg.ini", "obs.csv"))
    lines = obs.read_text().splitlines()
    lines[5] += ",1.0"
    obs.write_text("\n".join(lines) + "\n")
    raw = read_garpos(garpos)
    assert "expected 23 comma-separated fields, got 24" in raw.skipped["reason"].iloc[0]
    lines[1] = lines[1].replace(",TT,", ",XX,")
    obs.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"line 2: the header lacks column\(s\) \['TT'\]"):
        read_garpos(garpos)


@pytest.mark.parametrize(("old", "new", "message"), [
    (" Latitude0   = 38.00000000", " Latitude0   = 95", r"line 14 \(Latitude0\): Latitude0: "
                                                        r"expected a number in \[-90, 90\]"),
    (" Stations    = M01 M02 M03", " Stations    = M01 M01", "expected distinct transponder"),
    (" ATDoffset   =      1.5000", " ATDoffset   =      1.5x00", r"ATDoffset forward"),
    (" M02_dPos    =", " M02_dPos    = 1 2 3 4\n X", "expected '\\[section\\]' or 'key = value'"),
    ("[Site-parameter]", "[Site-parameters]", "no 'Latitude0' in \\[Site-parameter\\]"),
    # degrees, minutes, seconds: the first number was read as the latitude (a review)
    (" Latitude0   = 38.00000000", " Latitude0   = 38 30 00.0",
     r"line 14 \(Latitude0\): expected one number, got 3: '38 30 00.0' \(degrees, minutes"),
    (" Height0     = 25.00", " Height0     = 25.00 m", r"\(Height0\): expected one number, got 2"),
])
def test_garpos_site_file_errors_name_the_line(garpos, old, new, message):
    text = garpos.read_text()
    assert old in text
    garpos.write_text(text.replace(old, new, 1))
    with pytest.raises(InputError, match=message):
        read_garpos(garpos)


def test_garpos_profile_errors(garpos):
    svp = garpos.with_name(garpos.name.replace("initcfg.ini", "svp.csv"))
    lines = svp.read_text().splitlines()
    svp.write_text("\n".join(lines[:3] + ["50.0,abc"] + lines[4:]) + "\n")
    with pytest.raises(InputError, match=r"line 4, column 2 \(speed\)"):
        read_garpos(garpos)
    svp.write_text("\n".join(lines[:3] + ["10.0,1500"] + lines[4:]) + "\n")
    with pytest.raises(InputError, match="depths must increase"):
        read_garpos(garpos)


def _edit(path, line, text):
    lines = path.read_text().splitlines()
    lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n")


def test_gnatss_malformed_lines(gnatss):
    tt = gnatss.with_name("pxp_tt")
    lines = tt.read_text().splitlines()
    first = lines[0].split()
    _edit(tt, 2, "32-JAN-24 00:00:20.00 " + " ".join(first[2:]))
    _edit(tt, 3, " ".join(lines[2].split()[:3] + ["abc"] + lines[2].split()[4:]))
    _edit(tt, 4, " ".join(lines[3].split()[:3]))
    _edit(tt, 5, " ".join(lines[4].split()[:2] + ["0"] * 3))
    _edit(tt, 6, " ".join(lines[5].split()[:2] + ["-5"] + lines[5].split()[3:]))
    raw = read_gnatss(gnatss)
    why = dict(zip(raw.skipped["line"], raw.skipped["reason"], strict=True))
    assert "columns 1-2: expected a time like" in why[2]
    assert "column 4 (transponder M02, microseconds)" in why[3] and "'abc'" in why[3]
    assert "expected a date, a time and 3 travel times, got 3 fields" in why[4]
    assert why[5] == "no reply from any transponder"
    assert "column 3 (transponder M01" in why[6]
    assert set(raw.skipped["file"]) == {str(tt)}
    assert not {2, 3, 4, 5, 6} & set(raw.pings["line"])
    with pytest.raises(InputError, match=r"pxp_tt line 2: columns 1-2"):
        read_gnatss(gnatss, strict=True)


def test_gnatss_reply_without_a_position_is_skipped(gnatss):
    pos = gnatss.with_name("POS_FREED_TRANS_TWTT")
    lines = pos.read_text().splitlines()
    pos.write_text("\n".join(lines[:1] + lines[2:]) + "\n")  # the first reply's receive time
    raw = read_gnatss(gnatss)
    (reason,) = raw.skipped["reason"]
    assert reason.startswith("transponder") and "no position at the receive time" in reason
    pos.write_text("\n".join(lines[:1] + ["757339200.1 1 2 3"] + lines[1:]) + "\n")
    raw = read_gnatss(gnatss)
    assert "expected 13 numbers" in raw.skipped["reason"].iloc[0]


def test_gnatss_config_errors(gnatss, tmp_path):
    text = gnatss.read_text()
    gnatss.write_text(text.replace("lat: 38.0\n", "lat: 138.0\n", 1))
    with pytest.raises(InputError, match=r"config.yaml line \d+: solver.array_center.lat"):
        read_gnatss(gnatss)
    gnatss.write_text(text.replace("internal_delay: 0.2", "internal_delay: x", 1))
    with pytest.raises(InputError, match=r"solver.transponders.0.internal_delay: expected a"):
        read_gnatss(gnatss)
    gnatss.write_text(text + "  bad: [\n")
    with pytest.raises(InputError, match="not valid YAML"):
        read_gnatss(gnatss)
    gnatss.write_text(text.replace("transducer_delay_time: 0.13", "transducer_delay_time: 0.0"))
    with pytest.raises(InputError, match="do the files' timings align"):
        read_gnatss(gnatss)


def test_gnatss_wildcards_and_j2000_times(gnatss):
    tt = gnatss.with_name("pxp_tt")
    lines = tt.read_text().splitlines()
    half = len(lines) // 2
    (gnatss.parent / "day1").mkdir()
    (gnatss.parent / "day2").mkdir()
    (gnatss.parent / "day1" / "pxp_tt").write_text("\n".join(lines[:half]) + "\n")
    j2k = []
    for line in lines[half:]:  # the second day as seconds since J2000
        parts = line.split()
        t = pd.Timestamp(f"{parts[0]} {parts[1]}") - pd.Timestamp("2000-01-01 12:00:00")
        j2k.append(f"{t.total_seconds():.2f} " + " ".join(parts[2:]))
    (gnatss.parent / "day2" / "pxp_tt").write_text("\n".join(j2k) + "\n")
    tt.unlink()
    gnatss.write_text(gnatss.read_text().replace("path: pxp_tt", "path: day*/pxp_tt"))
    raw = read_gnatss(gnatss)
    assert len(raw.header["files"]["travel_times"]) == 2
    assert raw.pings["file"].nunique() == 2 and raw.pings["time"].min() == 0.0


def test_ecef_round_trip():
    x, y, z = geodetic_to_ecef(38.0, 143.0, -1500.0)
    e, n, u = ecef_to_enu(x, y, z, 38.0, 143.0, 25.0)
    assert (float(e), float(n), float(u)) == pytest.approx((0.0, 0.0, -1525.0), abs=1e-6)
    back = enu_to_ecef(e, n, u, 38.0, 143.0, 25.0)
    np.testing.assert_allclose(np.array(back, float), [x, y, z], atol=1e-6)


def test_a_campaign_with_every_line_skipped_says_why(garpos, gnatss):
    """The refusal names the commonest reasons and their first lines, and hints at the
    files' timings only where every reply lacked a position."""
    site = garpos.read_text()
    garpos.write_text(site.replace("M01", "m01").replace("M02", "m02").replace("M03", "m03"))
    with pytest.raises(InputError, match=r"no shot lines found \(\d+ lines skipped: \d+ lines: "
                       r"column 4 \(MT\): transponder 'M01' is not one of the site's Stations"
                       r".*\(first line 3\)"):
        read_garpos(garpos)
    cfg = gnatss.read_text()
    gnatss.write_text(cfg.replace("gps_sigma_limit: 0.05", "gps_sigma_limit: 1.0e-6"))
    with pytest.raises(InputError, match=r"no reply can be used .*above gps_sigma_limit 1e-06 m "
                       r"\(first pxp_tt line \d+\)\)$"):
        read_gnatss(gnatss)
    gnatss.write_text(cfg)
    tt = gnatss.with_name("pxp_tt")
    tt.write_text("\n".join(" ".join(ln.split()[:-1]) for ln in tt.read_text().splitlines()))
    with pytest.raises(InputError, match=r"travel times, got \d fields .*\(first pxp_tt line 1\)"
                       r"\)$"):  # a column short on every line: no hint about timings
        read_gnatss(gnatss)


def test_the_site_file_has_the_keys_garpos_itself_reads(garpos):
    """GARPOS's own output step reads Date(jday) and Ref.Frame, with no default."""
    text = garpos.read_text()
    assert " Date(UTC)   = 2024-01-01\n Date(jday)  = 2024-001\n Ref.Frame   = " in text
    assert len(read_garpos(garpos).pings) > 0
