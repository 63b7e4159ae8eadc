"""A survey as ranges, as two-way travel times, and in latitude/longitude: the same planes."""

import json

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.cli import main
from bayes_mpem.exceptions import InputError
from bayes_mpem.io.geodesy import enu_to_geodetic, geodetic_to_enu
from bayes_mpem.io.travel_time import convert_survey

C, TAT, ORIGIN = 1500.0, 0.013, (38.0, 143.0)


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    root = tmp_path_factory.mktemp("tt")
    assert main(["simulate", "--seed", "4", "--n-cycles", "150", "--out", str(root / "d")]) == 0
    return root, pd.read_csv(root / "d" / "pings.csv"), pd.read_csv(root / "d" / "beacons.csv")


def _planes(out):
    doc = json.loads((out / "summary.json").read_text())
    return {b: v["d0"] for b, v in doc["beacons"].items()}


def _as_lat_lon(frame):
    ll = [enu_to_geodetic(x, y, 0.0, *ORIGIN)[:2] for x, y in zip(frame["x"], frame["y"],
                                                                  strict=True)]
    lat, lon = np.array(ll).T
    out = frame.drop(columns=["x", "y"])
    out["lat"], out["lon"] = lat, lon
    return out


def test_ranges_travel_times_and_lat_lon_give_the_same_planes(survey, tmp_path):
    root, pings, beacons = survey
    b = root / "d" / "beacons.csv"
    assert main(["fit", str(root / "d" / "pings.csv"), "--beacons", str(b), "--out",
                 str(tmp_path / "ranges")]) == 0
    tt = pings.copy()
    tt["range"] = 2 * tt["range"] / C + TAT
    tt.to_csv(tmp_path / "twtt.csv", index=False)
    assert main(["fit", str(tmp_path / "twtt.csv"), "--beacons", str(b), "--out",
                 str(tmp_path / "twtt"), "--ranges", "two-way", "--travel-time",
                 "--sound-speed", str(C), "--turnaround", str(TAT)]) == 0
    _as_lat_lon(pings).to_csv(tmp_path / "ll_pings.csv", index=False)
    _as_lat_lon(beacons).to_csv(tmp_path / "ll_beacons.csv", index=False)
    assert main(["fit", str(tmp_path / "ll_pings.csv"), "--beacons",
                 str(tmp_path / "ll_beacons.csv"), "--out", str(tmp_path / "latlon")]) == 0
    ref = _planes(tmp_path / "ranges")
    assert ref and all(v is not None for v in ref.values())
    for name in ("twtt", "latlon"):
        got = _planes(tmp_path / name)
        assert got.keys() == ref.keys()
        for k in ref:
            assert abs(got[k] - ref[k]) < 0.01, (name, k, got[k], ref[k])
    cls = pd.read_csv(tmp_path / "twtt" / "classified.csv")
    np.testing.assert_allclose(cls["range"], pings["range"], atol=1e-9, equal_nan=True)
    assert "range_input" in cls.columns


def test_lat_lon_projection_against_a_reference():
    """The local frame of the package's geodesy against pymap3d's, where installed."""
    pm = pytest.importorskip("pymap3d")
    lat = np.array([38.01, 37.98, 38.0])
    lon = np.array([143.02, 142.97, 143.0])
    e, n, _ = geodetic_to_enu(lat, lon, np.zeros(3), *ORIGIN)
    e2, n2, _ = pm.geodetic2enu(lat, lon, np.zeros(3), *ORIGIN, 0.0)
    np.testing.assert_allclose(e, e2, atol=1e-6)
    np.testing.assert_allclose(n, n2, atol=1e-6)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"travel_time": True}, "need the sound speed"),
    ({"travel_time": True, "sound_speed": 1500.0, "turnaround": 50.0}, r"\[0, 10\] s"),
    ({"sound_speed": 1500.0}, "apply to --travel-time only"),
    ({"ranges": "three-way"}, "expected one of one-way, two-way"),
    ({"origin": (95.0, 0.0)}, "LAT,LON"),
])
def test_bad_options(survey, kwargs, message):
    root, *_ = survey
    with pytest.raises(InputError, match=message):
        convert_survey(root / "d" / "pings.csv", root / "d" / "beacons.csv", **kwargs)


def test_bad_cells_are_named(survey, tmp_path):
    root, pings, beacons = survey
    bad = pings.astype(object)
    bad.loc[4, "range"] = "abc"
    bad.loc[6, "range"] = 0.005  # shorter than the turn-around time
    bad.to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(InputError) as err:
        convert_survey(tmp_path / "bad.csv", root / "d" / "beacons.csv", travel_time=True,
                       sound_speed=1500.0, turnaround=0.013)
    text = str(err.value)
    assert "line 6, column 'range'" in text and "line 8, column 'range'" in text
    mixed = _as_lat_lon(beacons)
    mixed.to_csv(tmp_path / "llb.csv", index=False)
    with pytest.raises(InputError, match="the same way in both"):
        convert_survey(root / "d" / "pings.csv", tmp_path / "llb.csv")
