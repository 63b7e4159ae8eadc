"""Real time: classify each range as it arrives and keep the vehicle's position.

The navigation model of :mod:`bayes_mpem.lbl.navigate`, run recursively:
:class:`Navigator` takes one line at a time (a ping, a ping without reply, or
a dead-reckoning line) and answers at once with the reply's class
probabilities and the filtered position, at a constant cost and in constant
memory. The forward filter is in :mod:`.ekf`, the online EM of the reflectors
in :mod:`.reflector`, the start (provisional answers, then a small batch fit)
in :mod:`.warmup`, the per-ping arithmetic in :mod:`.kernel`, and the loop in
:mod:`.navigator`.
"""

from .navigator import Navigator, PingResult

__all__ = ["Navigator", "PingResult"]
