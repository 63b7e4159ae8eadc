"""Tests of the shared validators (bayes_mpem._validate)."""

import math

import numpy as np
import pytest

from bayes_mpem._validate import (
    check_choice,
    check_finite,
    check_int,
    check_positive,
    check_probability,
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
