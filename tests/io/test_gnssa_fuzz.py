"""What the independent fuzz of the GNSS-A inputs found (``benchmarks/gnssa_fuzz.py``).

Every test breaks one file of a small simulated campaign (or of the shipped SeaGap sample) the
way the fuzz did, and checks the fix: a clear error naming the file and the line, column or
key, or the line skipped with its reason; never a value read silently otherwise.
"""

import contextlib
import io
import os

import pytest
import yaml

from bayes_mpem.cli import main
from bayes_mpem.exceptions import InputError
from bayes_mpem.io.formats import sniff_format
from bayes_mpem.io.garpos import read_garpos, write_garpos
from bayes_mpem.io.gnatss import read_gnatss, write_gnatss
from bayes_mpem.io.seagap import read_seagap
from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa


@pytest.fixture(scope="module")
def sim():
    return simulate_gnssa(n_transponders=3, hours=0.5, rng=4)


@pytest.fixture()
def garpos(sim, tmp_path):
    return write_garpos(tmp_path / "garpos", sim.pings, sim.header)


@pytest.fixture()
def gnatss(sim, tmp_path):
    return write_gnatss(tmp_path / "gnatss", sim.pings, sim.header)


@pytest.fixture()
def seagap(seagap_copy):
    return seagap_copy(120)


def _site(garpos, key, value):
    """Set ``key = value`` in the site file; return the line number."""
    lines = garpos.read_text().splitlines()
    k = next(i for i, s in enumerate(lines) if s.split("=")[0].strip() == key)
    lines[k] = f" {key} = {value}"
    garpos.write_text("\n".join(lines) + "\n")
    return k + 1


def _obs(garpos):
    return garpos.with_name(garpos.name.replace("initcfg.ini", "obs.csv"))


def _svp(garpos):
    return garpos.with_name(garpos.name.replace("initcfg.ini", "svp.csv"))


def _reasons(raw):
    return dict(zip(raw.skipped["line"], raw.skipped["reason"], strict=True))


# --------------------------------------------------------------------------- GARPOS


@pytest.mark.parametrize("sigma", ["abc", "nan", "-3", "inf"])
def test_garpos_position_sigma_must_be_a_number_of_0_or_more(garpos, sigma):
    # was: 'abc' and 'nan' read as free (None / NaN), '-3' as 3
    pos = "-487.9274 -564.7417 -1493.9435"
    line = _site(garpos, "M01_dPos", f"{pos} {sigma} 3 3")
    with pytest.raises(InputError, match=rf"line {line} \(M01_dPos\): M01_dPos sigma_E"):
        read_garpos(garpos)


def test_garpos_centre_shift_out_of_range_is_refused(garpos):
    # was: added to every transponder, an internal error (TypeError) deep in the fit
    line = _site(garpos, "dCentPos", "0 0 1e9 0 0 0")
    with pytest.raises(InputError, match=rf"line {line} \(dCentPos\): dCentPos up"):
        read_garpos(garpos)
    _site(garpos, "dCentPos", "0 0 3000 0 0 0")  # in range, but lifts M01 above the sea
    with pytest.raises(InputError, match=r"\(M01_dPos\): up \+ dCentPos up"):
        read_garpos(garpos)


@pytest.mark.parametrize(("value", "why"), [("nope.csv", "'nope.csv' not found"),
                                             ("", "expected a file name"),
                                             (".", "'.' is a folder")])
def test_garpos_named_file_errors_name_the_site_file_line(garpos, value, why):
    # was: "'nope.csv' not found (looked at ...)" without the site file or its key
    line = _site(garpos, "datacsv", value)
    with pytest.raises((InputError, FileNotFoundError),
                       match=rf"initcfg.ini line {line} \(datacsv\): {why}"):
        read_garpos(garpos)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_garpos_named_pipe_is_not_reported_as_not_found(garpos):
    fifo = garpos.parent / "pipe.csv"
    os.mkfifo(fifo)
    line = _site(garpos, "datacsv", "pipe.csv")
    with pytest.raises(InputError, match=rf"line {line} \(datacsv\): 'pipe.csv' is not a "
                                         r"regular file \(.*a pipe, device or socket\)"):
        read_garpos(garpos)


@pytest.mark.parametrize("spelt", ["Latitude0\u200b", "latitude0"])
def test_garpos_a_key_spelt_nearly_names_its_line(garpos, spelt):
    # was: "no 'Latitude0' in [Site-parameter]" with no line (a zero-width space is invisible)
    text = garpos.read_text()
    line = next(i for i, t in enumerate(text.splitlines(), start=1)
                if t.strip().startswith("Latitude0"))
    garpos.write_text(text.replace("Latitude0", spelt, 1))
    with pytest.raises(InputError, match=rf"no 'Latitude0' in \[Site-parameter\]; line {line} "
                                         r"gives '[Ll]atitude0.*invisible characters"):
        read_garpos(garpos)


def test_garpos_a_key_in_another_section_says_so(garpos):
    lines = garpos.read_text().splitlines()
    i = next(k for k, t in enumerate(lines) if t.strip().startswith("Latitude0"))
    moved = lines.pop(i)
    lines.append(moved)  # the last section is not [Site-parameter]
    garpos.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=rf"no 'Latitude0' in \[Site-parameter\]; line "
                                         rf"{len(lines)} gives it in \[[\w-]+\] \(the wrong "
                                         r"section\?\)"):
        read_garpos(garpos)


def test_garpos_profile_order_names_the_line(garpos):
    lines = _svp(garpos).read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    _svp(garpos).write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"svp.csv line 7, column 1 \(depth\): depths must"):
        read_garpos(garpos)


def test_garpos_profile_must_reach_the_transponders(garpos):
    # depths in km: read as a profile 1.5 m deep, the speed below held for 1,500 m
    lines = _svp(garpos).read_text().splitlines()
    km = [lines[0]] + [f"{float(s.split(',')[0]) / 1000:.5f},{s.split(',')[1]}"
                       for s in lines[1:]]
    _svp(garpos).write_text("\n".join(km) + "\n")
    with pytest.raises(InputError, match=r"svp.csv: the sound-speed profile ends at .* above "
                                         r"the deepest transponder"):
        read_garpos(garpos)


def test_garpos_profile_must_start_near_the_surface(garpos):
    # was (session 46's hunt): a cast whose top 1,400 m were cut, its first speed held up to
    # the surface without a word; the centre moved about 1 cm
    lines = _svp(garpos).read_text().splitlines()
    deep = [lines[0]] + [s for s in lines[1:] if float(s.split(",")[0]) >= 1400.0]
    _svp(garpos).write_text("\n".join(deep) + "\n")
    with pytest.raises(InputError, match=r"svp.csv: the sound-speed profile starts at 14\d\d m, "
                                         r"below a tenth of the deepest transponder's depth"):
        read_garpos(garpos)


def test_garpos_header_naming_a_column_twice_is_refused(garpos):
    # was: the second TT (a residual column renamed) silently used as the travel time
    lines = _obs(garpos).read_text().splitlines()
    lines[1] = lines[1].replace(",ResiTT,", ",TT,")
    _obs(garpos).write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"obs.csv line 2: the header names column\(s\) \['TT'\]"):
        read_garpos(garpos)


def test_garpos_repeated_shot_is_skipped_with_the_first_line(garpos):
    # was: fitted twice (one shot, double weight)
    lines = _obs(garpos).read_text().splitlines()
    lines.insert(11, lines[10].replace(lines[10].split(",")[0], "999", 1))
    _obs(garpos).write_text("\n".join(lines) + "\n")
    raw = read_garpos(garpos)
    assert 12 not in set(raw.pings["line"]) and 11 in set(raw.pings["line"])
    assert "a second shot of" in _reasons(raw)[12] and "line 11" in _reasons(raw)[12]


def test_garpos_stations_with_commas_name_the_stations_line(garpos):
    line = _site(garpos, "Stations", "M01,M02,M03")
    with pytest.raises(InputError, match=rf"line {line} \(Stations\): expected distinct "
                                         "transponder names separated by spaces"):
        read_garpos(garpos)


# --------------------------------------------------------------------------- GNATSS


def _tt(gnatss, k, fn):
    p = gnatss.with_name("pxp_tt")
    lines = p.read_text().splitlines()
    lines = fn(lines, k)
    p.write_text("\n".join(lines) + "\n")


def test_gnatss_extra_travel_time_is_skipped(gnatss):
    # was: the fourth travel time of a three-transponder config silently dropped
    _tt(gnatss, 5, lambda ls, k: ls[:k] + [ls[k] + " 2500000"] + ls[k + 1:])
    raw = read_gnatss(gnatss)
    assert 6 not in set(raw.pings["line"])
    assert "expected a date, a time and 3 travel times, got 6 fields" in _reasons(raw)[6]


def test_gnatss_repeated_interrogation_is_skipped(gnatss):
    _tt(gnatss, 5, lambda ls, k: ls[:k + 1] + [ls[k]] + ls[k + 1:])
    raw = read_gnatss(gnatss)
    assert 7 not in set(raw.pings["line"]) and 6 in set(raw.pings["line"])
    assert "a second interrogation at the time of pxp_tt line 6" in _reasons(raw)[7]


def test_gnatss_two_positions_at_one_time_are_not_used(gnatss):
    # was: the later position silently replaced the earlier one
    p = gnatss.with_name("POS_FREED_TRANS_TWTT")
    lines = p.read_text().splitlines()
    parts = lines[0].split()
    parts[1] = f"{float(parts[1]) + 500:.4f}"
    p.write_text("\n".join(lines[:1] + [" ".join(parts)] + lines[1:]) + "\n")
    raw = read_gnatss(gnatss)
    assert 1 not in set(raw.pings["line"])  # the first interrogation transmits at that time
    assert "two different positions at" in _reasons(raw)[1]


def test_gnatss_negative_variance_skips_the_position(gnatss):
    # was: its absolute value taken
    p = gnatss.with_name("POS_FREED_TRANS_TWTT")
    lines = p.read_text().splitlines()
    parts = lines[0].split()
    parts[4] = "-" + parts[4]
    p.write_text("\n".join([" ".join(parts)] + lines[1:]) + "\n")
    raw = read_gnatss(gnatss)
    pos = raw.skipped[raw.skipped["file"] == str(p)]
    assert list(pos["line"]) == [1]
    assert "column 5 (covariance): a variance of" in pos["reason"].iloc[0]
    assert 1 not in set(raw.pings["line"])


@pytest.mark.parametrize(("text", "why"), [("", "no data line"), ("\n \n\n", "no data line"),
                                           ("1 2 3\nx\n", "2 lines skipped: ")])
def test_gnatss_positions_file_with_no_usable_position_is_named(gnatss, text, why):
    # was: every travel time skipped for "no position ... in the positions file", the
    # refusal naming pxp_tt
    p = gnatss.with_name("POS_FREED_TRANS_TWTT")
    p.write_text(text)
    with pytest.raises(InputError, match="no position can be used") as err:
        read_gnatss(gnatss)
    assert str(err.value).startswith(f"{p}: ") and why in str(err.value)


def test_gnatss_positions_all_given_twice_differently_say_so(gnatss):
    p = gnatss.with_name("POS_FREED_TRANS_TWTT")
    lines = [ln for ln in p.read_text().splitlines() if ln.strip()]
    moved = []
    for ln in lines:
        parts = ln.split()
        parts[1] = repr(float(parts[1]) + 1.0)
        moved.append(" ".join(parts))
    p.write_text("\n".join(lines + moved) + "\n")
    with pytest.raises(InputError, match=f"{len(lines)} times given twice with different "
                                         "positions, the first two different positions at"):
        read_gnatss(gnatss)


def _config(gnatss, fn):
    data = yaml.safe_load(gnatss.read_text())
    fn(data)
    gnatss.write_text(yaml.safe_dump(data, sort_keys=False))


def test_gnatss_std_dev_must_be_true_or_false(gnatss):
    # was: bool('maybe') -> True
    _config(gnatss, lambda d: d["solver"].update(std_dev="maybe"))
    with pytest.raises(InputError, match=r"config.yaml line \d+ \(solver.std_dev\): expected "
                                         "true or false, got 'maybe'"):
        read_gnatss(gnatss)


def test_gnatss_key_given_twice_is_refused(gnatss):
    # was: YAML keeps the last value silently
    lines = gnatss.read_text().splitlines()
    k = next(i for i, s in enumerate(lines) if "geoid_undulation" in s)
    lines.insert(k + 1, lines[k].split(":")[0] + ": 35.0")
    gnatss.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=rf"line {k + 2} \(geoid_undulation\): 'geoid_undulation' "
                                         rf"given twice in one mapping \(first at line {k + 1}\)"):
        read_gnatss(gnatss)


def test_gnatss_sound_speed_pattern_matching_two_casts_is_refused(gnatss):
    # was (session 46's hunt): both read, the first's speed kept at every shared depth
    (gnatss.parent / "ctd_sv").rename(gnatss.parent / "ctd_sv_day1")
    (gnatss.parent / "ctd_sv_day2").write_text((gnatss.parent / "ctd_sv_day1").read_text())
    _config(gnatss, lambda d: d["solver"]["input_files"]["sound_speed"].update(path="ctd_sv_*"))
    with pytest.raises(InputError, match=r"\(solver.input_files.sound_speed.path\): matches 2 "
                                         r"files \(ctd_sv_day1, ctd_sv_day2\); expected one"):
        read_gnatss(gnatss)


def test_gnatss_missing_input_file_names_the_config_line(gnatss):
    _config(gnatss, lambda d: d["solver"]["input_files"]["travel_times"].update(path="nope"))
    with pytest.raises(FileNotFoundError, match=r"config.yaml line \d+ "
                                                r"\(solver.input_files.travel_times.path\): "
                                                "'nope' not found"):
        read_gnatss(gnatss)


# --------------------------------------------------------------------------- SeaGap


def test_seagap_profile_order_names_the_line(seagap):
    # was: "SoundSpeedProfile: depth[6] = 25.0 is not greater ..." without the file
    p = seagap.with_name("ss_prof.inp")
    lines = p.read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"ss_prof.inp line 7, column 1 \(depth\): depths must"):
        read_seagap(seagap)


def test_seagap_profile_of_one_level_is_refused(seagap):
    p = seagap.with_name("ss_prof.inp")
    p.write_text(p.read_text().splitlines()[0] + "\n")
    with pytest.raises(InputError, match=r"ss_prof.inp: a sound-speed profile needs 2 or more"):
        read_seagap(seagap)


def test_seagap_second_lever_arm_is_refused(seagap):
    # was: the second line silently ignored
    seagap.with_name("tr-ant.inp").write_text("0.37 17.7 -11.5\n1.0 2.0 3.0\n")
    with pytest.raises(InputError, match=r"tr-ant.inp line 2: a second lever arm"):
        read_seagap(seagap)


def test_seagap_receive_before_transmit_is_skipped(seagap):
    # was: a receive time 5e8 s before the transmit time fitted as a shot
    lines = seagap.read_text().splitlines()
    parts = lines[49].split()
    parts[9] = "1"
    lines[49] = " ".join(parts)
    seagap.write_text("\n".join(lines) + "\n")
    raw = read_seagap(seagap)
    assert 50 not in set(raw.pings["line"])
    assert "t_rx (column 10): expected 0-120 s after t_tx" in _reasons(raw)[50]


def test_seagap_repeated_shot_is_skipped(seagap):
    lines = seagap.read_text().splitlines()
    seagap.write_text("\n".join(lines[:41] + [lines[40]] + lines[41:]) + "\n")
    raw = read_seagap(seagap)
    assert 42 not in set(raw.pings["line"]) and "(the first is line 41" in _reasons(raw)[42]


def test_seagap_one_bad_line_among_the_first_is_still_seagap(seagap):
    # was: "not a survey format bayes-mpem recognises", the bad line not named
    lines = seagap.read_text().splitlines()
    lines[1] = " ".join(lines[1].split()[:17])
    seagap.write_text("\n".join(lines) + "\n")
    assert sniff_format(seagap) == "seagap"
    assert "expected 18 numbers" in _reasons(read_seagap(seagap))[2]


def test_a_folder_as_survey_is_named_a_folder(tmp_path):
    # was: "survey file not found"
    with pytest.raises(InputError, match="is a folder; expected a file"):
        sniff_format(tmp_path)


# --------------------------------------------------------------------------- the array


def test_too_few_shots_names_the_shots_file(garpos):
    # was: "no transponder has 6 shots or more (...)" without a file
    lines = _obs(garpos).read_text().splitlines()
    k = lines[1].split(",").index("flag")
    for i in range(2, len(lines)):
        parts = lines[i].split(",")
        parts[k] = "True"
        lines[i] = ",".join(parts)
    _obs(garpos).write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"obs.csv: no transponder has \d+ shots or more"):
        locate_array_survey(read_garpos(garpos))


def test_shots_from_one_place_are_refused(garpos):
    # was: exit 0 with a transponder 1e12 m deep and null intervals
    lines = _obs(garpos).read_text().splitlines()
    cols = lines[1].split(",")
    ks = [cols.index(c) for c in ("ant_e0", "ant_n0", "ant_e1", "ant_n1")]
    for i in range(2, len(lines)):
        parts = lines[i].split(",")
        for k in ks:
            parts[k] = "10.0"
        lines[i] = ",".join(parts)
    _obs(garpos).write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"obs.csv: every shot was transmitted within 1 m"):
        array_shots(read_garpos(garpos))


def test_command_line_refuses_with_status_2_and_no_result(garpos, tmp_path):
    # was: exit 1, "internal error: TypeError"
    line = _site(garpos, "dCentPos", "0 0 1e9 0 0 0")
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["locate", str(garpos), "--out", str(tmp_path / "out")])
    assert code == 2
    msg = err.getvalue().strip()
    assert len(msg.splitlines()) == 1 and f"line {line} (dCentPos)" in msg
    assert not (tmp_path / "out" / "summary.json").exists()
