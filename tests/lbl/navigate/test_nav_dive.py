"""Epochs, the dead reckoning at them, and what the dive refuses."""

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.survey import load_survey
from bayes_mpem.lbl.navigate.dive import build_dive

BEACONS = pd.DataFrame({"beacon": ["A", "B"], "x": [0.0, 800.0], "y": [0.0, 0.0],
                        "depth": [1000.0, 1000.0]})


def _pings(**cols):
    base = {"time": [0.0, 0.0, 10.0, 10.0, 20.0], "beacon": ["A", "B", "A", "B", "A"],
            "range": [1000.0, 1300.0, np.nan, 1290.0, 1001.0], "x": [0.0, 0.0, 5.0, 5.0, 10.0],
            "y": [0.0] * 5, "depth": [10.0, 10.0, 11.0, 11.0, 12.0]}
    base.update(cols)
    return pd.DataFrame(base)


def test_epochs_are_the_distinct_ping_times():
    d = build_dive(load_survey(_pings(), BEACONS))
    assert d.n_epochs == 3 and d.n == 4
    np.testing.assert_array_equal(d.epoch, [0, 0, 1, 2])
    np.testing.assert_array_equal(d.epoch_of_row, [0, 0, 1, 1, 2])
    np.testing.assert_array_equal(d.rows, [0, 1, 3, 4])
    np.testing.assert_allclose(d.dr, [[0, 0], [5, 0], [10, 0]])
    np.testing.assert_allclose(d.depth, [10, 11, 12])
    # fewer than MIN_WINDOW_REPLIES replies: the window of all replies
    np.testing.assert_allclose(d.window, [[1000, 1300], [1000, 1300]])


def test_pings_of_one_time_must_agree_on_the_dead_reckoning():
    with pytest.raises(InputError, match=r"time 10.0 s \(row 2, row 3\) .*'x', 'y'"):
        build_dive(load_survey(_pings(x=[0.0, 0.0, 5.0, 7.0, 10.0]), BEACONS))


def test_a_position_table_is_interpolated_to_the_epochs():
    dr = pd.DataFrame({"time": [-5.0, 5.0, 25.0], "x": [100.0, 200.0, 200.0], "y": [0, 10, 30]})
    d = build_dive(load_survey(_pings(), BEACONS), dr)
    np.testing.assert_allclose(d.dr, [[150, 5], [200, 15], [200, 25]])
    assert "positions" in d.dr_source


def test_a_velocity_table_is_integrated_from_the_first_ping_position():
    dr = pd.DataFrame({"time": [0.0, 10.0, 20.0], "ve": [1.0, 1.0, 3.0], "vn": [0.0, 0.5, 0.5]})
    d = build_dive(load_survey(_pings(x=[7.0, 7.0, 0.0, 0.0, 0.0]), BEACONS), dr)
    np.testing.assert_allclose(d.dr, [[7, 0], [17, 2.5], [37, 7.5]])


def test_pings_outside_the_dead_reckoning_table_are_refused():
    dr = pd.DataFrame({"time": [0.0, 15.0], "x": [0.0, 1.0], "y": [0.0, 0.0]})
    with pytest.raises(InputError, match=r"row 4, column 'time': 20.0 s is outside"):
        build_dive(load_survey(_pings(), BEACONS), dr)


def _commented_csv(path, frame):
    """``frame`` as CSV under two comment lines and a blank one (the header on line 4)."""
    path.write_text("# exported by the nav box\n# units: m\n\n" + frame.to_csv(index=False))
    return str(path)


def _grep_n(path, prefix):
    """The line number ``grep -n`` gives the first line of ``path`` starting with ``prefix``."""
    with open(path) as fh:
        return next(i for i, line in enumerate(fh, 1) if line.startswith(prefix))


def test_dead_reckoning_span_error_names_the_file_line_and_ends(tmp_path):
    pings = _commented_csv(tmp_path / "p.csv", _pings())
    dr = pd.DataFrame({"time": [0.0, 15.0], "x": [0.0, 1.0], "y": [0.0, 0.0]})
    with pytest.raises(InputError) as err:
        build_dive(load_survey(pings, BEACONS), dr)
    line = _grep_n(pings, "20.0,")
    assert line == 9
    msg = str(err.value)
    assert f"p.csv line {line}, column 'time': 20.0 s is outside" in msg
    assert msg.endswith("1 ping(s) are outside it (times 20.0 to 20.0 s); expected a "
                        "dead-reckoning table that spans every ping")


def test_pings_of_one_time_that_disagree_are_named_by_file_line(tmp_path):
    pings = _commented_csv(tmp_path / "p.csv", _pings(x=[0.0, 0.0, 5.0, 7.0, 10.0]))
    with pytest.raises(InputError, match=r"time 10.0 s \(line 7, line 8\) give dead-reckoned"):
        build_dive(load_survey(pings, BEACONS))
    assert _grep_n(pings, "10.0,A") == 7 and _grep_n(pings, "10.0,B") == 8


def test_a_dive_without_any_reply_is_refused():
    with pytest.raises(InputError, match="no ping has a reply"):
        build_dive(load_survey(_pings(range=[np.nan] * 5), BEACONS))


def test_a_dive_rebuilt_from_its_dead_reckoning_is_the_same():
    from bayes_mpem.lbl.navigate.dive import dive_with_dead_reckoning
    from bayes_mpem.lbl.navigate.simulate import simulate_dive

    sim = simulate_dive("random", rng=3, n_cycles=60)
    a = build_dive(sim.survey)
    b = dive_with_dead_reckoning(sim.survey, a.times, a.dr)
    for name in ("times", "dr", "depth", "epoch_of_row", "rows", "epoch", "beacon", "z",
                 "zdepth", "beacon_xyz", "window", "d0_min"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    with pytest.raises(InputError, match="epochs"):
        dive_with_dead_reckoning(sim.survey, a.times[1:], a.dr[1:])
    with pytest.raises(InputError, match="shape"):
        dive_with_dead_reckoning(sim.survey, a.times, a.dr[:, :1])
