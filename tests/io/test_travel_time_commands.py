"""Travel times, two-way ranges, lat/lon and a sound-speed profile for every LBL command.

``tests/io/test_travel_time.py`` checks ``fit``; here ``navigate`` (the same planes and
track within 1 cm), the other commands' options, ``--ssp`` and the file lines named in the
messages after a conversion.
"""

import json

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.acoustics.profile import SoundSpeedProfile
from bayes_mpem.cli import main
from bayes_mpem.cli.parser import UNIT_COMMANDS, build_parser
from bayes_mpem.exceptions import InputError
from bayes_mpem.io.geodesy import enu_to_geodetic
from bayes_mpem.io.travel_time import convert_survey

C, TAT, ORIGIN = 1500.0, 0.013, (38.0, 143.0)


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    root = tmp_path_factory.mktemp("ttc")
    assert main(["simulate", "--seed", "4", "--n-cycles", "150", "--out", str(root / "d")]) == 0
    return root, pd.read_csv(root / "d" / "pings.csv"), pd.read_csv(root / "d" / "beacons.csv")


def _as_lat_lon(frame):
    ll = [enu_to_geodetic(x, y, 0.0, *ORIGIN)[:2] for x, y in zip(frame["x"], frame["y"],
                                                                  strict=True)]
    lat, lon = np.array(ll).T
    out = frame.drop(columns=["x", "y"])
    out["lat"], out["lon"] = lat, lon
    return out


def _navigated(out):
    doc = json.loads((out / "summary.json").read_text())
    planes = {b: v["d0"]["estimate"] for b, v in doc["beacons"].items()}
    return planes, pd.read_csv(out / "track.csv")


def test_navigate_gives_the_same_planes_and_track_from_every_input(survey, tmp_path):
    root, pings, beacons = survey
    b = str(root / "d" / "beacons.csv")
    assert main(["navigate", str(root / "d" / "pings.csv"), "--beacons", b, "--out",
                 str(tmp_path / "ranges")]) == 0
    tt = pings.copy()
    tt["range"] = 2 * tt["range"] / C + TAT
    tt.to_csv(tmp_path / "twtt.csv", index=False)
    assert main(["navigate", str(tmp_path / "twtt.csv"), "--beacons", b, "--out",
                 str(tmp_path / "twtt"), "--ranges", "two-way", "--travel-time",
                 "--sound-speed", str(C), "--turnaround", str(TAT)]) == 0
    _as_lat_lon(pings).to_csv(tmp_path / "llp.csv", index=False)
    _as_lat_lon(beacons).to_csv(tmp_path / "llb.csv", index=False)
    assert main(["navigate", str(tmp_path / "llp.csv"), "--beacons", str(tmp_path / "llb.csv"),
                 "--origin", f"{ORIGIN[0]},{ORIGIN[1]}", "--out", str(tmp_path / "ll")]) == 0
    ref_planes, ref_track = _navigated(tmp_path / "ranges")
    assert ref_planes and all(v is not None for v in ref_planes.values())
    for name in ("twtt", "ll"):
        planes, track = _navigated(tmp_path / name)
        assert planes.keys() == ref_planes.keys()
        for k, v in ref_planes.items():
            assert abs(planes[k] - v) < 0.01, (name, k, planes[k], v)
        for col in ("x", "y"):
            np.testing.assert_allclose(track[col], ref_track[col], atol=0.01, err_msg=name)


@pytest.mark.parametrize("command", UNIT_COMMANDS)
def test_every_lbl_command_takes_the_input_units(command):
    args = build_parser().parse_args(
        [command, "p.csv", "--beacons", "b.csv", "--out", "o", "--ranges", "two-way",
         "--travel-time", "--ssp", "ssp.txt", "--turnaround", "0.01", "--origin", "38,143"])
    assert (args.ranges, args.travel_time, args.travel_ssp, args.turnaround, args.origin) == (
        "two-way", True, "ssp.txt", 0.01, (38.0, 143.0))


def test_a_profile_converts_with_the_harmonic_mean_between_the_depths(survey, tmp_path):
    root, pings, beacons = survey
    prof = SoundSpeedProfile([0.0, 1000.0, 5000.0], [1520.0, 1490.0, 1550.0])
    tt = pings.copy()
    tt["range"] = tt["range"] / C + TAT  # one-way travel times, from a mean speed C
    tt.to_csv(tmp_path / "tt.csv", index=False)
    p, _ = convert_survey(tmp_path / "tt.csv", root / "d" / "beacons.csv", travel_time=True,
                          ssp=prof, turnaround=TAT)
    depth_of = dict(zip(beacons["beacon"].astype(str), beacons["depth"], strict=True))
    c = prof.harmonic_mean(pings["depth"], pings["beacon"].astype(str).map(depth_of))
    np.testing.assert_allclose(p["range"], (tt["range"] - TAT) * c, rtol=1e-12)
    assert not np.allclose(p["range"], pings["range"], rtol=1e-3, equal_nan=True)
    # a constant profile is the constant speed
    flat = SoundSpeedProfile.constant(C)
    p, _ = convert_survey(tmp_path / "tt.csv", root / "d" / "beacons.csv", travel_time=True,
                          ssp=flat, turnaround=TAT)
    np.testing.assert_allclose(p["range"], pings["range"], rtol=1e-9)
    with pytest.raises(InputError, match="not both"):
        convert_survey(tmp_path / "tt.csv", root / "d" / "beacons.csv", travel_time=True,
                       ssp=flat, sound_speed=C)
    with pytest.raises(InputError, match="apply to --travel-time only"):
        convert_survey(tmp_path / "tt.csv", root / "d" / "beacons.csv", ssp=flat)


def test_errors_after_a_conversion_name_the_file_line(survey, tmp_path, capsys):
    root, pings, _ = survey
    bad = pings.astype(object)
    bad["range"] = 2 * pings["range"] / C
    bad.loc[9, "depth"] = "deep"  # read after the conversion, by the survey's reader
    bad.to_csv(tmp_path / "bad.csv", index=False)
    code = main(["sample", str(tmp_path / "bad.csv"), "--beacons", str(root / "d" / "beacons.csv"),
                 "--out", str(tmp_path / "o"), "--ranges", "two-way", "--travel-time",
                 "--sound-speed", str(C)])
    err = capsys.readouterr().err
    assert code == 2
    assert "bad.csv line 11, column 'depth'" in err and "DataFrame" not in err


def test_ssp_from_the_command_line(survey, tmp_path):
    """``--ssp FILE`` with a constant profile gives the planes of ``--sound-speed``."""
    root, pings, _ = survey
    tt = pings.copy()
    tt["range"] = tt["range"] / C + TAT
    tt.to_csv(tmp_path / "tt.csv", index=False)
    (tmp_path / "ssp.txt").write_text(f"depth speed\n0 {C}\n6000 {C}\n")
    b = str(root / "d" / "beacons.csv")
    units = ["--travel-time", "--turnaround", str(TAT)]
    assert main(["fit", str(tmp_path / "tt.csv"), "--beacons", b, "--out", str(tmp_path / "c"),
                 "--sound-speed", str(C), *units]) == 0
    assert main(["fit", str(tmp_path / "tt.csv"), "--beacons", b, "--out", str(tmp_path / "s"),
                 "--ssp", str(tmp_path / "ssp.txt"), *units]) == 0
    planes = [json.loads((tmp_path / d / "summary.json").read_text())["beacons"] for d in "cs"]
    assert planes[0].keys() == planes[1].keys()
    for k in planes[0]:
        assert abs(planes[0][k]["d0"] - planes[1][k]["d0"]) < 1e-6


def test_a_batch_manifest_with_input_units_says_how_to_convert(survey, tmp_path, capsys):
    root, *_ = survey
    (tmp_path / "m.csv").write_text(f"name,pings,beacons,travel_time\n"
                                    f"a,{root / 'd' / 'pings.csv'},{root / 'd' / 'beacons.csv'},"
                                    "true\n")
    assert main(["batch", str(tmp_path / "m.csv"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "line 2, column 'travel_time'" in err and "convert_survey" in err
