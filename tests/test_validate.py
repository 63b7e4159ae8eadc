"""Tests of the shared validators (bayes_mpem._validate)."""

import math

import numpy as np
import pytest

from bayes_mpem._validate import (
    check_choice,
    check_finite,
    check_increasing,
    check_int,
    check_positive,
    check_probability,
    check_range,
)


@pytest.mark.parametrize("value", [1, 2.5, np.float32(3.0), np.int64(7), "4"])
def test_check_positive_accepts(value):
    out = check_positive("x", value)
    assert isinstance(out, float) and out == float(value)


@pytest.mark.parametrize("value", [0, -1.0, math.nan, math.inf, None, True, "a", [1.0]])
def test_check_positive_refuses(value):
    with pytest.raises(ValueError, match=r"^x: expected a positive number, got "):
        check_positive("x", value)


def test_check_positive_none():
    assert check_positive("x", None, allow_none=True) is None
    with pytest.raises(ValueError, match="expected a positive number or None, got -2"):
        check_positive("x", -2, allow_none=True)


def test_check_finite():
    assert check_finite("x", -3) == -3.0
    for bad in (math.nan, -math.inf, "b", None, False):
        with pytest.raises(ValueError, match=r"^x: expected a finite number, got "):
            check_finite("x", bad)


def test_check_probability():
    assert check_probability("ci", 0.5) == 0.5
    for bad in (0.0, 1.0, -0.1, 1.5, math.nan, "x", None):
        with pytest.raises(ValueError, match=r"^ci: expected a probability in \(0, 1\), got "):
            check_probability("ci", bad)
    assert check_probability("w", 0, open_interval=False) == 0.0
    assert check_probability("w", 1, open_interval=False) == 1.0
    with pytest.raises(ValueError, match=r"^w: expected a probability in \[0, 1\], got 1.01"):
        check_probability("w", 1.01, open_interval=False)


def test_check_choice():
    assert check_choice("path", "double", ["triangle", "double"]) == "double"
    with pytest.raises(ValueError, match=r"^path: expected one of \('a', 'b'\), got 'c'"):
        check_choice("path", "c", ("a", "b"))
    with pytest.raises(ValueError, match="expected one of"):
        check_choice("path", ["unhashable"], ("a", "b"))


def test_check_int():
    assert check_int("n", np.int32(5), minimum=1) == 5
    assert type(check_int("n", np.int32(5), minimum=1)) is int
    for bad in (0, 2.0, True, "3", None):
        with pytest.raises(ValueError, match=r"^n: expected an integer >= 1, got "):
            check_int("n", bad, minimum=1)


def test_check_positive_what():
    assert check_positive("c", 1500, what="a positive sound speed in m/s") == 1500.0
    with pytest.raises(ValueError, match=r"^c: expected a positive sound speed in m/s, got -1$"):
        check_positive("c", -1, what="a positive sound speed in m/s")


def test_check_choice_words():
    assert check_choice("w", "equal", ("learned", "equal"), words=True) == "equal"
    with pytest.raises(ValueError, match=r"^w: expected 'learned' or 'equal', got 'free'$"):
        check_choice("w", "free", ("learned", "equal"), words=True)
    with pytest.raises(ValueError, match=r"^s: expected 'a', 'b' or 'c', got 'd'$"):
        check_choice("s", "d", "abc", words=True)
    with pytest.raises(ValueError, match=r"^s: expected one of \('a',\), got 'd'$"):
        check_choice("s", "d", ("a",), words=True)


@pytest.mark.parametrize(("kw", "value", "ok"), [
    ({"low": 0, "high": 1}, 0.5, True),
    ({"low": 0, "high": 1}, 0, False),
    ({"low": 0, "high": 1}, 1, False),
    ({"low": 0, "high": 1, "include_high": True}, 1, True),
    ({"low": 0, "high": 1, "include_low": True}, 0, True),
    ({"low": 0, "include_low": True}, 0, True),
    ({"low": 0, "include_low": True}, math.inf, True),
    ({"low": 0, "include_low": True}, -1e-12, False),
    ({"high": 2}, -math.inf, True),
    ({"high": 2}, 2, False),
    ({}, 3.5, True),
    ({"low": 0, "include_low": True}, math.nan, False),
    ({"low": 0, "include_low": True}, True, False),
    ({"low": 0, "include_low": True}, "x", False),
    ({"low": 0, "include_low": True}, None, False),
])
def test_check_range(kw, value, ok):
    if ok:
        out = check_range("x", value, **kw)
        assert isinstance(out, float) and out == float(value)
    else:
        with pytest.raises(ValueError, match=r"^x: expected a number"):
            check_range("x", value, **kw)


@pytest.mark.parametrize(("kw", "what"), [
    ({"low": 0, "high": 1}, r"a number in \(0, 1\)"),
    ({"low": 0, "high": 1, "include_high": True}, r"a number in \(0, 1\]"),
    ({"low": -1, "high": 1, "include_low": True}, r"a number in \[-1, 1\)"),
    ({"low": 0, "include_low": True}, "a number >= 0"),
    ({"low": 0}, "a number > 0"),
    ({"high": 0}, "a number < 0"),
    ({"high": 0, "include_high": True}, "a number <= 0"),
    ({}, "a number"),
])
def test_check_range_wording(kw, what):
    with pytest.raises(ValueError, match=rf"^x: expected {what}, got nan$"):
        check_range("x", math.nan, **kw)


def test_check_increasing():
    out = check_increasing("z", [0, 1, 5])
    assert out.dtype == float and out.tolist() == [0.0, 1.0, 5.0]
    assert check_increasing("z", [3.0]).tolist() == [3.0]
    assert check_increasing("z", []).size == 0
    with pytest.raises(ValueError, match=r"^P: z\[2\] = 1.0 is not greater than z\[1\] = 1.0: "
                                         r"expected increasing depths$"):
        check_increasing("z", [0.0, 1.0, 1.0, 0.5], context="P: ", what="increasing depths")
    with pytest.raises(ValueError, match=r"z\[1\] = -1.0 is not greater than z\[0\] = 0.0: "
                                         "expected strictly increasing values"):
        check_increasing("z", [0.0, -1.0])
