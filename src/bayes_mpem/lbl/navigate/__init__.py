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

from .driver import navigate
from .result import Navigation
from .simulate import DiveSimulation, simulate_dive

__all__ = ["DiveSimulation", "Navigation", "navigate", "simulate_dive"]
