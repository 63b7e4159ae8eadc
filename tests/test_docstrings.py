"""Every docstring example of the package runs (doctests of every module)."""

import doctest
import importlib
import pkgutil

import pytest

import bayes_mpem

MODULES = sorted(m.name for m in pkgutil.walk_packages(bayes_mpem.__path__, "bayes_mpem."))


@pytest.mark.parametrize("name", MODULES)
def test_examples(name):
    mod = importlib.import_module(name)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


def test_examples_exist():
    """Modules with public functions show how to call them somewhere (counted, not run:
    test_examples runs them)."""
    finder = doctest.DocTestFinder()
    found = sum(len(t.examples) for n in MODULES
                for t in finder.find(importlib.import_module(n)))
    assert found > 20
