"""Navigation: the vehicle's track jointly with every range's class and each reflector.

The pings' ``x``, ``y`` are a drifting dead reckoning; :func:`navigate`
estimates the horizontal track at every ping epoch with its uncertainty, the
dead reckoning's heading bias and speed scale, per beacon the reflector and
the class of every range, using the multipath replies as position information.
The per-ping pieces are in :mod:`.model`, the data in :mod:`.dive`, the
objective and its sparse normal equations in :mod:`.objective` and
:mod:`.normal`, the ECM in :mod:`.ecm`, the flags of an uncorrected track in
:mod:`.observability`, the result in :mod:`.result` and the simulator of dives in
:mod:`.simulate`.
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
