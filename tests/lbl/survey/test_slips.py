"""The usual slips with a survey's tables, each named once with its likely cause."""

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.batch import BatchTask, run_task
from bayes_mpem.cli import main
from bayes_mpem.lbl.survey.slips import (
    MAX_EXAMPLES,
    MAX_MESSAGE,
    SlipError,
    impossible_rows,
    load_checked,
)


@pytest.fixture(scope="module")
def dive(tmp_path_factory):
    root = tmp_path_factory.mktemp("slips")
    assert main(["simulate", "--seed", "3", "--n-cycles", "150", "--out", str(root / "d")]) == 0
    return root, pd.read_csv(root / "d" / "pings.csv"), pd.read_csv(root / "d" / "beacons.csv")


def _files(root, name, pings, beacons):
    p, b = root / f"{name}-pings.csv", root / f"{name}-beacons.csv"
    pings.to_csv(p, index=False)
    beacons.to_csv(b, index=False)
    return p, b


def _with(frame, **columns):
    out = frame.copy()
    for k, f in columns.items():
        out[k] = f(out[k])
    return out


SLIPS = {
    "seconds": (lambda p: _with(p, range=lambda r: r / 1500.0), None,
                "one-way travel times in seconds"),
    "two_way_seconds": (lambda p: _with(p, range=lambda r: 2 * r / 1500.0), None,
                        "two-way travel times in seconds"),
    "km": (lambda p: _with(p, range=lambda r: r / 1000.0), None, "ranges in kilometres"),
    "two_way": (lambda p: _with(p, range=lambda r: 2 * r), None, "two-way ranges"),
    "depth_sign": (lambda p: _with(p, depth=lambda d: -d), None, "positive up"),
    "depth_sign_beacons": (None, lambda b: _with(b, depth=lambda d: -d), "positive up"),
    "beacon_ids": (None, lambda b: _with(b, beacon=lambda s: "B" + s.astype(str)),
                   "spelled differently"),
    "other_survey": (None, lambda b: _with(b, beacon=lambda s: "X" + (s * 7).astype(str)),
                     "different surveys"),
    # a hunt (session 48): fitted at exit 0, d0 805-1543 m (truth 2392-2491), warned only as
    # "no coherent multipath band"
    "xy_swapped": (lambda p: p.rename(columns={"x": "y", "y": "x"}), None,
                   "the pings' x and y swapped"),
    "axis_sign": (lambda p: _with(p, x=lambda x: -x), None, "the pings' x with the wrong sign"),
}


@pytest.mark.parametrize("name", sorted(SLIPS))
def test_each_slip_is_named_once(dive, name, tmp_path):
    root, pings, beacons = dive
    fp, fb, words = SLIPS[name]
    p, b = _files(tmp_path, name, fp(pings) if fp else pings, fb(beacons) if fb else beacons)
    with pytest.raises(SlipError) as err:
        load_checked(p, b)
    text = str(err.value)
    assert err.value.slip == name.replace("_beacons", "").replace("other_survey", "beacon_ids")
    assert words in text and len(text) < MAX_MESSAGE
    assert text.count("\n") <= MAX_EXAMPLES + 1  # at most ten example lines and a count


def test_the_two_files_swapped(dive, tmp_path):
    root, pings, beacons = dive
    p, b = _files(tmp_path, "ok", pings, beacons)
    with pytest.raises(SlipError, match="look swapped") as err:
        load_checked(b, p)
    assert err.value.slip == "swapped" and str(p) in str(err.value)
    with pytest.raises(SlipError, match="looks like a pings table"):
        load_checked(p, p)


def test_a_clean_survey_is_no_slip_and_other_errors_pass_through(dive, tmp_path):
    root, pings, beacons = dive
    p, b = _files(tmp_path, "ok", pings, beacons)
    assert len(load_checked(p, b)) == len(pings)
    bad = pings.astype(object)
    bad.loc[3, "range"] = "abc"
    p2, _ = _files(tmp_path, "bad", bad, beacons)
    with pytest.raises(Exception, match="line 5, column 'range'") as err:
        load_checked(p2, b)
    assert not isinstance(err.value, SlipError)


def test_fit_refuses_a_slip_with_one_short_message(dive, tmp_path, capsys):
    root, pings, beacons = dive
    p, b = _files(tmp_path, "s", SLIPS["two_way_seconds"][0](pings), beacons)
    assert main(["fit", str(p), "--beacons", str(b), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "two-way travel times in seconds" in err and len(err.encode()) < 4096
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["compare", "sample"])
@pytest.mark.parametrize("name", ["two_way", "two_way_seconds"])
def test_compare_and_sample_name_the_slip_as_fit_does(dive, tmp_path, capsys, command, name):
    """``compare`` (and ``sample``) on two-way ranges skipped every beacon ("the EM solution
    ... is not a credible reflector") and wrote an empty result, exit 0, the slip unnamed."""
    root, pings, beacons = dive
    fp, _, words = SLIPS[name]
    p, b = _files(tmp_path, name, fp(pings), beacons)
    assert main([command, str(p), "--beacons", str(b), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert words in err and str(p) in err and "direct path" in err
    assert "SkippedBeaconWarning" not in err and not (tmp_path / "o").exists()


def test_a_slip_is_failed_not_done_in_batch(dive, tmp_path):
    root, pings, beacons = dive
    p, b = _files(tmp_path, "km", SLIPS["km"][0](pings), beacons)
    record = run_task(BatchTask("k", "fit", {"pings": str(p), "beacons": str(b)}, {"rng": 0}),
                      str(tmp_path / "out"))
    assert record["status"] == "failed" and "kilometres" in record["reason"]


def test_ranges_shorter_than_the_vertical_distance_are_flagged_per_row(dive, tmp_path):
    root, pings, beacons = dive
    short = pings.copy()
    bz = beacons.set_index("beacon").loc[short["beacon"], "depth"].to_numpy()
    far = short["range"].notna() & (np.abs(bz - short["depth"]) > 30)
    rows = short.index[far][[5, 40, 77]]
    short.loc[rows, "range"] = 2.0  # the beacons are more than 30 m above or below
    p, b = _files(tmp_path, "short", short, beacons)
    survey = load_checked(p, b)
    flagged = impossible_rows(survey)
    assert set(rows) <= set(flagged)
    assert all("shorter than the" in flagged[r] for r in rows)
    assert all(survey.range[r] < abs(bz[r] - survey.depth[r]) for r in flagged)
    assert main(["fit", str(p), "--beacons", str(b), "--out", str(tmp_path / "o")]) == 0
    cls = pd.read_csv(tmp_path / "o" / "classified.csv", keep_default_na=False)
    assert cls.loc[rows, "reason"].str.contains("no acoustic path is that short").all()


def test_every_length_in_kilometres_is_warned_of(dive, tmp_path):
    """A hunt (session 48): ranges, positions and depths all in km fit the direct path as
    well as metres; the fit gave d0 of 2.39 for 2,392 m, warned only of sigma_MP's floor."""
    from bayes_mpem.exceptions import FitQualityWarning

    root, pings, beacons = dive
    km = {c: (lambda v: v / 1000.0) for c in ("range", "x", "y", "depth")}
    p, b = _files(tmp_path, "km", _with(pings, **km),
                  _with(beacons, **{c: km[c] for c in ("x", "y", "depth")}))
    with pytest.warns(FitQualityWarning, match=r"every range \(up to [\d.]+\) and beacon depth "
                                               r"\(up to [\d.]+\) is under 20 m: if these are "
                                               "kilometres, give metres"):
        load_checked(p, b)
