"""The cells of input tables: wording, beacon ids, problems collected into one error."""

import numpy as np
import pytest

from bayes_mpem.exceptions import InputError
from bayes_mpem.io.cells import MAX_LISTED, Problems, as_beacon_id, is_missing, show


def test_problems_are_listed_in_row_order_and_counted_beyond_the_first_ten():
    problems = Problems("pings.csv")
    problems.add(5, "line 7: late")
    problems.add_mask(np.arange(30) % 2 == 0, lambda pos: f"line {pos + 2}: even")
    with pytest.raises(InputError) as info:
        problems.raise_if_any()
    lines = str(info.value).splitlines()
    assert lines[0] == "16 problems in pings.csv:"
    assert lines[1:4] == ["  line 2: even", "  line 4: even", "  line 6: even"]
    assert "  line 7: late" in lines[:MAX_LISTED + 1]
    assert lines[-1] == f"  ... and {16 - MAX_LISTED} more problems"


def test_one_problem_is_the_message_itself_and_none_raises_nothing():
    Problems("b.csv").raise_if_any()
    problems = Problems("b.csv")
    problems.add(0, "line 2, column 'x': expected a number, got 'a'")
    with pytest.raises(InputError, match=r"^line 2, column 'x': expected a number, got 'a'$"):
        problems.raise_if_any()


@pytest.mark.parametrize(("value", "expected"), [
    (4.0, "4"), (np.int64(7), "7"), (" B2 ", "B2"), (1.7, "1.7"), (float("nan"), ""),
    (None, ""), (True, "True")])
def test_beacon_ids_have_one_form(value, expected):
    assert as_beacon_id(value) == expected


def test_missing_cells_are_named():
    assert is_missing(float("nan")) and is_missing(None) and not is_missing(0.0)
    assert show("") == "an empty cell" and show(np.float64("nan")) == "a missing value (NaN)"
    assert show(list(range(40))).endswith("...")
