"""Real time: classify each range as it arrives and keep the vehicle's position.

:class:`Navigator` runs the model of :mod:`bayes_mpem.lbl.navigate` recursively, one line
at a time, at a constant cost and memory (``docs/stream.md``).
"""

from .navigator import Navigator, PingResult

__all__ = ["Navigator", "PingResult"]
