"""Run the Examples sections of the public modules as doctests."""

import doctest
import importlib

import pytest

MODULES = ["geometry", "mixture", "em", "simulate", "fitting", "data", "plots", "bayes",
           "readers", "locate", "locate_bayes", "sampling", "compare", "bayes_plots", "acoustics",
           "refraction",
           "simcheck"]


@pytest.mark.parametrize("name", MODULES)
def test_examples(name):
    mod = importlib.import_module(f"bayes_mpem.{name}")
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
