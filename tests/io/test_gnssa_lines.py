"""GARPOS and GNATSS files: lines end at ``\\n`` only; ``2.5_0`` refused; profiles checked."""

import re

import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.fields import number
from bayes_mpem.io.garpos import read_garpos, write_garpos
from bayes_mpem.io.gnatss import read_gnatss, write_gnatss
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa


@pytest.fixture(scope="module")
def sim():
    return simulate_gnssa(n_transponders=3, hours=0.2, rng=4, origin=(38.0, 143.0, 25.0))


@pytest.fixture()
def garpos(sim, tmp_path):
    return write_garpos(tmp_path / "garpos", sim.pings, sim.header)


@pytest.fixture()
def gnatss(sim, tmp_path):
    return write_gnatss(tmp_path / "gnatss", sim.pings, sim.header, transducer_delay=0.13)


@pytest.mark.parametrize("text", ["2.5_0", "1_000", "_1"])
def test_underscores_are_refused(text):
    with pytest.raises(ValueError, match="expected a number"):
        number(text, "TT", lo=0.0)


@pytest.mark.parametrize("char", ["\r", "\f", "\u2028", "\v"])
def test_garpos_a_stray_break_stays_inside_its_line(garpos, char):
    obs = garpos.with_name(garpos.name.replace("initcfg.ini", "obs.csv"))
    lines = obs.read_text().split("\n")
    n_rows = len(read_garpos(garpos).pings)
    parts = lines[6].split(",")
    parts[4] = parts[4][:3] + char + parts[4][3:]  # inside TT of line 7
    lines[6] = ",".join(parts)
    lines[0] += char + "a break in a comment"
    obs.write_text("\n".join(lines))
    raw = read_garpos(garpos)
    assert len(raw.pings) == n_rows - 1  # one line, one shot, no header trouble
    (row,) = raw.skipped.itertuples()
    assert row.line == 7 and "column 5 (TT" in row.reason
    assert set(raw.pings["line"]) >= {8, len(lines) - 1}  # later numbers not shifted


def test_garpos_underscore_in_a_shot_is_skipped(garpos):
    obs = garpos.with_name(garpos.name.replace("initcfg.ini", "obs.csv"))
    lines = obs.read_text().splitlines()
    parts = lines[6].split(",")
    parts[4] = parts[4][:3] + "_" + parts[4][3:]
    lines[6] = ",".join(parts)
    obs.write_text("\n".join(lines) + "\n")
    (row,) = read_garpos(garpos).skipped.itertuples()
    assert row.line == 7 and "column 5 (TT" in row.reason


@pytest.mark.parametrize("char", ["\r", "\f", "\u2028"])
def test_gnatss_a_stray_break_is_refused_with_its_column(gnatss, char):
    tt = gnatss.with_name("pxp_tt")
    lines = tt.read_text().split("\n")
    spans = [m.span() for m in re.finditer(r"\S+", lines[3])]
    at = spans[3][0] + 2  # inside the 4th field
    lines[3] = lines[3][:at] + char + lines[3][at:]
    tt.write_text("\n".join(lines))
    raw = read_gnatss(gnatss)
    why = dict(zip(raw.skipped["line"], raw.skipped["reason"], strict=True))
    assert list(why) == [4] and "column 4" in why[4]


@pytest.mark.parametrize(("swap", "message"), [
    (lambda ls: [ls[0], ls[2], ls[1], *ls[3:]], "expected heights going down"),
    (lambda ls: [ls[0], ls[1], ls[1], *ls[2:]], "a repeated or swapped level"),
    # depths written positive: the second level is above the first (a review)
    (lambda ls: [ln.replace("-", "", 1) if ln.lstrip().startswith("-") else ln for ln in ls],
     r"negative below the sea surface.*or depths given positive\?"),
])
def test_gnatss_profile_swapped_or_repeated_depths(gnatss, swap, message):
    sv = gnatss.with_name("ctd_sv")
    lines = sv.read_text().splitlines()
    sv.write_text("\n".join(swap(lines)) + "\n")
    with pytest.raises(InputError, match=rf"ctd_sv line \d+, column 1 \(depth\).*{message}"):
        read_gnatss(gnatss)
