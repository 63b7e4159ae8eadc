"""Sentinel of benchmarks/navigate_ship.py (issue 25's acceptance study, 20 dives, in
docs/navigate.md): one short staggered ship dive, this model against the reference
navigators of benchmarks/navigate_reference.py."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[3] / "benchmarks"


def _load(name):
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location(name, BENCH / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(BENCH))
    return mod


@pytest.fixture(scope="module")
def row():
    return _load("navigate_ship").ship_dive(1, n_cycles=400)


def test_ship_study_sentinel(row):
    me = row["this model"]
    assert abs(me["sigma"] / 0.2 - 1) <= 0.2
    assert me["mp"] == 0
    assert 0.85 <= me["n_in"] / me["n_cov"] <= 0.995
    best = min(row[m]["rmse"] for m in ("trilateration", "EKF + RTS (true sigma)",
                                        "EKF + RTS (estimated sigma)"))
    assert me["rmse"] <= 1.05 * best


def test_reference_navigators_are_sane(row):
    """The baselines are real competitors: the EKF finds the noise level, trilateration fixes."""
    assert abs(row["EKF + RTS (estimated sigma)"]["sigma"] / 0.2 - 1) <= 0.25
    assert row["EKF + RTS (true sigma)"]["rmse"] < 1.0
    assert np.isfinite(row["trilateration"]["rmse"]) and row["trilateration"]["rmse"] < 1.5
    lines, acc = _load("navigate_ship").summarise([row], [])
    assert len(lines) == 7 and acc[0].startswith("* sigma_DP")
