"""Navigation: the vehicle's track jointly with every range's class and each reflector.

:func:`navigate` corrects a drifting dead reckoning with the ranges, multipath replies
included, and returns the track with its uncertainty (``docs/navigate.md``).
"""

import importlib

#: public name -> its module; loaded on first use (PEP 562), so the command line can read
#: :mod:`.options` without loading numpy
_PUBLIC = {"navigate": "driver", "Navigation": "result", "DiveSimulation": "simulate",
           "simulate_dive": "simulate"}


def __getattr__(name):
    """Load a public name of the package on first use."""
    if name in _PUBLIC:
        value = getattr(importlib.import_module(f"{__name__}.{_PUBLIC[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    """List the public names with the module's own."""
    return sorted({*globals(), *_PUBLIC})


__all__ = ["DiveSimulation", "Navigation", "navigate", "simulate_dive"]
