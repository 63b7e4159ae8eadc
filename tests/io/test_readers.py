"""Readers for measured surveys: every sample file, every line accounted for, bad lines."""

from pathlib import Path

import numpy as np
import pytest

import bayes_mpem as bm
from bayes_mpem.exceptions import InputError, LocateWarning
from bayes_mpem.io.formats import read_survey
from bayes_mpem.io.geodesy import geodetic_to_enu

DATA = Path(__file__).resolve().parents[2] / "data"
SAMPLES = [("obsrange/SIO_CC03.txt", "obsrange-sio", 88, 33),
           ("obsrange/SIO_EC03.txt", "obsrange-sio", 49, 40),
           ("obsrange/SIO_WC03.txt", "obsrange-sio", 49, 74),
           ("obsrange/WHOI_S05.txt", "obsrange-whoi", 244, 0),
           ("seagap/obsdata.inp", "seagap", 3347, 0)]


@pytest.mark.parametrize(("name", "fmt", "n_pings", "n_skipped"), SAMPLES)
def test_every_sample_file_reads_and_converts(name, fmt, n_pings, n_skipped):
    raw = read_survey(DATA / name, fmt)
    assert len(raw.pings) == n_pings and len(raw.skipped) == n_skipped
    pings, beacons = raw.to_pings()
    survey = bm.load_survey(pings, beacons)
    assert len(survey) == n_pings and not survey.no_reply.any()
    # every line is a ping, a skipped line, or header / comment / blank
    text = (DATA / name).read_text(encoding="utf-8-sig").splitlines()
    accounted = set(raw.pings["line"]) | set(raw.skipped["line"])
    for i, line in enumerate(text, start=1):
        if i not in accounted:
            s = line.strip()
            assert (not s or s.startswith("#") or ":" in s or set(s) == {"="}), (i, line)


def test_sio_header_and_skipped_reason():
    raw = read_survey(DATA / "obsrange/SIO_CC03.txt", "obsrange-sio")
    assert raw.header == {"site": "CC03", "lat": -4.88241, "lon": -132.68907, "depth": 4750.0}
    assert raw.skipped["reason"].str.startswith("deck box: Timeout").all()
    first = raw.pings.iloc[0]
    assert first["twtt"] == pytest.approx(6.306)
    assert first["lat"] == pytest.approx(-(4 + 52.9270 / 60)) and first["time"] == 0.0
    assert raw.pings["time"].iloc[1] == pytest.approx(11.0)


def test_whoi_parse_agrees_with_the_deck_box_range():
    """The deck box's own 'rng m' is 1500 m/s x twtt / 2 (rounded): our parse must agree."""
    raw = read_survey(DATA / "obsrange/WHOI_S05.txt", "obsrange-whoi")
    assert raw.header["tat"] == pytest.approx(0.013) and raw.header["sound_speed"] == 1500.0
    pings, _ = raw.to_pings(sound_speed=1500.0, tat=0.0)
    assert np.max(np.abs(pings["range"] - raw.pings["rng_m"])) <= 1.0


def test_seagap_companions_and_sound_speed():
    raw = read_survey(DATA / "seagap/obsdata.inp", "seagap")
    tp = raw.header["transponders"]
    assert list(tp.index) == ["1", "2", "3", "4"]
    assert np.all((-tp["up"] > 2680) & (-tp["up"] < 2740))
    assert raw.header["tr_ant"].shape == (3,)
    _, beacons = raw.to_pings()
    prof = raw.header["ss_prof"]
    keep = prof["depth"] <= -tp["up"].mean()
    c = 1 / np.mean(1 / prof.loc[keep, "sound_speed"])
    assert 1480 < c < 1500  # the data README's harmonic mean: ~1489 m/s
    assert set(beacons["beacon"]) == {"1", "2", "3", "4"}


def _sio(tmp_path, body):
    p = tmp_path / "sio.txt"
    p.write_text("Site:   T1\nDrop Point (Latitude):  -4.9\nDrop Point (Longitude): -132.7\n"
                 "Depth (meters):  4750\n=====\n\n" + body)
    return p


GOOD_SIO = (" 6306 msec. Lat: 4 52.9270 S  Lon: 132 41.4272 W  Alt: 29.42 "
            "Time(UTC): 2018:114:06:04:30\n")


def test_sio_malformed_line_is_skipped_with_reason_or_strict_error(tmp_path):
    p = _sio(tmp_path, GOOD_SIO + " 63O6 msec. Lat: garbled\n" + GOOD_SIO.replace(":30\n", ":41\n"))
    raw = read_survey(p, "obsrange-sio")
    assert len(raw.pings) == 2 and list(raw.skipped["line"]) == [8]
    assert "not a ping line" in raw.skipped["reason"].iloc[0]
    with pytest.raises(InputError, match=r"sio.txt line 8: not a ping line.*63O6"):
        read_survey(p, "obsrange-sio", strict=True)


@pytest.mark.parametrize("name", ["obsrange/SIO_CC03.txt", "obsrange/WHOI_S05.txt"])
def test_a_deck_box_log_with_repeated_ping_lines_is_refused(tmp_path, name):
    """Ping lines given twice were each counted as a reply (intervals narrower by up to
    sqrt 2); now refused, the file, both lines of each pair and the count named."""
    lines = (DATA / name).read_text(encoding="utf-8-sig").splitlines(keepends=True)
    raw = read_survey(DATA / name)
    first, second = (int(n) for n in raw.pings["line"].iloc[[0, 5]])
    twice = lines[:first] + [lines[first - 1]] + lines[first:second] + [lines[second - 1]] \
        + lines[second:]
    p = tmp_path / Path(name).name
    p.write_text("".join(twice), encoding="utf-8")
    with pytest.raises(InputError) as err:
        read_survey(p)
    text = str(err.value)
    assert text.startswith(f"{p}: 2 ping lines repeat an earlier one")
    assert f"line {first + 1} repeats line {first}" in text
    assert f"line {second + 2} repeats line {second + 1}" in text
    # a time given twice with two travel times (SIO_WC03's lines 11 and 12) is two replies
    raw = read_survey(DATA / "obsrange/SIO_WC03.txt")
    assert list(raw.pings["line"].iloc[:2]) == [11, 12] and raw.pings["time"].iloc[1] == 0.0


def test_sio_bad_header_number(tmp_path):
    p = tmp_path / "h.txt"
    p.write_text("Drop Point (Latitude):  minus four\n=====\n" + GOOD_SIO)
    with pytest.raises(InputError, match=r"h.txt line 1: header 'Drop Point \(Latitude\)'"):
        read_survey(p, "obsrange-sio")


def test_sio_invalid_day_of_year(tmp_path):
    p = _sio(tmp_path, GOOD_SIO.replace("2018:114", "2018:999"))
    with pytest.raises(InputError, match="no ping lines found"):
        read_survey(p, "obsrange-sio")
    with pytest.raises(InputError, match="invalid time \\(day of year 999 outside 1-365\\)"):
        read_survey(p, "obsrange-sio", strict=True)


def test_whoi_malformed_lines(tmp_path):
    head = "# TAT:  13 ms\n# Speed of Sound:  1500 m/s\n# Drop-Point Latitude:  01 35.6114 N\n" \
           "# Drop-Point Longitude: 91 48.5609 W\n# Drop-Point Depth (m): 2318\n"
    good = "2023-04-06 05:10:05,  2329,  3106, 01 35.6648 N, 091 48.5082 W, 05:10:03.00, 84.1\n"
    bad = ["2023-04-06 05:10:05,  2329,  3106, 01 35.6648 N, 091 48.5082 W, 84.1\n",
           "2023-04-06 05:10:05,  2329,  -3, 01 35.6648 N, 091 48.5082 W, 05:10:03.00, 84.1\n",
           "2023-04-06 05:10:05,  2329,  3106, 1.5935 N, 091 48.5082 W, 05:10:03.00, 84.1\n"]
    p = tmp_path / "w.txt"
    p.write_text(head + good + "".join(bad) + good.replace("05:10:05", "05:10:17"))
    raw = read_survey(p, "obsrange-whoi")
    assert len(raw.pings) == 2 and list(raw.skipped["line"]) == [7, 8, 9]
    reasons = " | ".join(raw.skipped["reason"])
    assert "expected 7 comma-separated fields, got 6" in reasons
    assert "outside (0, 150] s" in reasons and "DD MM.MMMM H" in reasons
    with pytest.raises(InputError, match=r"w.txt line 7: expected 7"):
        read_survey(p, "obsrange-whoi", strict=True)


def test_seagap_malformed_rows_and_companions(tmp_path):
    src = (DATA / "seagap/obsdata.inp").read_text().splitlines()
    (tmp_path / "obsdata.inp").write_text("\n".join([src[0], " ".join(src[1].split()[:17]),
                                                     src[2]]) + "\n")
    (tmp_path / "pxp-ini.inp").write_text((DATA / "seagap/pxp-ini.inp").read_text())
    # no lever arm: the 18 columns are the antenna's (was: located from it without a word)
    with pytest.raises(InputError, match=r"tr-ant.inp: not found beside obsdata.inp; expected "
                                         "SeaGap's lever arm"):
        read_survey(tmp_path / "obsdata.inp", "seagap")
    (tmp_path / "tr-ant.inp").write_text((DATA / "seagap/tr-ant.inp").read_text())
    with pytest.warns(LocateWarning, match="no sound-speed profile beside it"):
        raw = read_survey(tmp_path / "obsdata.inp", "seagap")
    assert len(raw.pings) == 2 and "expected 18 numbers" in raw.skipped["reason"].iloc[0]
    assert raw.header["files"]["ss_prof"] is None
    (tmp_path / "ss_prof.zv").write_text((DATA / "seagap/ss_prof.inp").read_text())
    raw = read_survey(tmp_path / "obsdata.inp", "seagap")  # SeaGap's own default name
    assert raw.header["files"]["ss_prof"].endswith("ss_prof.zv") and "ss_prof" in raw.header
    assert raw.header["ss_prof_source"] == "ss_prof.zv"  # named as read (was ss_prof.inp)
    (tmp_path / "tr-ant.inp").write_text("0.37 17.7\n")
    with pytest.raises(InputError, match=r"tr-ant.inp line 1: expected 3 numbers"):
        read_survey(tmp_path / "obsdata.inp", "seagap")


def test_missing_unknown_and_empty(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.txt"):
        read_survey(tmp_path / "nope.txt", "obsrange-sio")
    with pytest.raises(ValueError, match="format: expected one of"):
        read_survey(tmp_path / "x", "csv")
    (tmp_path / "empty.txt").write_text("# only a comment\n")
    with pytest.raises(InputError, match="no ping lines found"):
        read_survey(tmp_path / "empty.txt", "obsrange-whoi")


def test_geodetic_to_enu_known_distances():
    e, n, u = geodetic_to_enu(0.0, 0.001, 0.0, 0.0, 0.0)
    assert e == pytest.approx(111.3195, abs=1e-3) and abs(n) < 1e-9
    e, n, u = geodetic_to_enu(1 / 60, 0.0, 0.0, 0.0, 0.0)  # one arc-minute north at the equator
    assert n == pytest.approx(1842.90, abs=0.05)
    e, n, u = geodetic_to_enu(-4.88241, -132.68907, 100.0, -4.88241, -132.68907)
    assert abs(e) < 1e-6 and abs(n) < 1e-6 and u == pytest.approx(100.0, abs=1e-6)


def test_antenna_to_transducer_rotations():
    from bayes_mpem.io.geodesy import antenna_to_transducer

    z = np.zeros(1)
    # zero attitude: the offset is added as it is
    np.testing.assert_allclose(antenna_to_transducer(z, z, z, z, z, z, [1.0, 2.0, 3.0]),
                               [[1.0], [2.0], [3.0]], atol=1e-12)
    # heading 90 deg turns the offset by -90 deg about the vertical: (1, 0, 0) -> (0, -1, 0)
    out = antenna_to_transducer(z, z, z, np.full(1, 90.0), z, z, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(np.ravel(out), [0.0, -1.0, 0.0], atol=1e-12)
    # pitch 90 deg at heading 0 turns about the east axis: (0, 1, 0) -> (0, 0, 1)
    out = antenna_to_transducer(z, z, z, z, np.full(1, 90.0), z, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(np.ravel(out), [0.0, 0.0, 1.0], atol=1e-12)
    # any attitude keeps the lever arm's length
    rng = np.random.default_rng(0)
    h, p, r = rng.uniform(-180, 180, 50), rng.uniform(-10, 10, 50), rng.uniform(-10, 10, 50)
    e, n, u = antenna_to_transducer(np.zeros(50), np.zeros(50), np.zeros(50), h, p, r,
                                    [0.37, 17.72, -11.52])
    np.testing.assert_allclose(np.sqrt(e**2 + n**2 + u**2), np.hypot(np.hypot(0.37, 17.72),
                                                                      11.52))


def test_seagap_lever_arm_is_what_makes_the_straight_ray_fit_work():
    """Measured gain of applying tr-ant.inp: rms from 4-6 ms to about 0.3 ms."""
    import dataclasses
    import warnings

    from bayes_mpem.survey_in.location import locate

    raw = read_survey(DATA / "seagap/obsdata.inp", "seagap")
    pxp = raw.header["transponders"]
    no_arm = dataclasses.replace(raw, header={k: v for k, v in raw.header.items()
                                              if k != "tr_ant"})
    for tid in ("1", "2", "3", "4"):
        with_arm = locate(*raw.to_pings(), tid, tat=0.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            without = locate(*no_arm.to_pings(), tid, tat=0.0)
        assert 1e3 * with_arm.sigma < 0.5 < 3.0 < 1e3 * without.sigma
        assert abs(with_arm.sound_speed - 1489.0) < 2.0
        assert abs(with_arm.east - pxp.loc[tid, "east"]) < 3.0
        assert abs(with_arm.north - pxp.loc[tid, "north"]) < 3.0
        assert abs(with_arm.depth + pxp.loc[tid, "up"]) < 3.0
