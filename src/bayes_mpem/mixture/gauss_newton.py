"""The safeguard of a Gauss-Newton M-step: halve the step until the objective does not increase.

A generalised EM needs an M-step that does not decrease the expected complete-data
log-likelihood: :func:`safeguarded_step` tries a Gauss-Newton step, halving it until the
weighted objective does not increase, so the log-likelihood never decreases.

Examples
--------
Minimise ``(x - 3)**2`` from ``x = 0`` with a step that overshoots:

>>> out = safeguarded_step(lambda x: ((x - 3.0) ** 2, None), 0.0, 10.0, 9.0)
>>> out.x, out.value, out.step
(5.0, 4.0, 5.0)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

#: Halvings tried before a step is given up.
MAX_HALVINGS = 30


class Step(NamedTuple):
    """An accepted step of :func:`safeguarded_step`.

    Attributes
    ----------
    x : float or numpy.ndarray
        The new point (within the bounds).
    value : float
        The objective there (no larger than at the start).
    aux : object
        What the objective returned with its value (e.g. residuals or a
        parameter object built from ``x``).
    step : float or numpy.ndarray
        The step finally taken, before projection into the bounds.
    """

    x: Any
    value: float
    aux: Any
    step: Any


def safeguarded_step(objective: Callable, x, step, value, *, bounds=None,
                     max_halvings: int = MAX_HALVINGS) -> Step | None:
    """Take ``step`` from ``x``, halving it until ``objective`` does not increase.

    Parameters
    ----------
    objective : callable
        ``objective(x) -> (value, aux)``, or ``None`` where ``x`` is infeasible
        (then the step is halved as for an increase).
    x : float or numpy.ndarray
        The current point.
    step : float or numpy.ndarray
        The proposed (Gauss-Newton) step.
    value : float
        The objective at ``x``.
    bounds : tuple of float, optional
        ``(lo, hi)``: every candidate ``x + step`` is clipped into them (a
        scalar ``x`` with ``min(max(x + step, lo), hi)``).
    max_halvings : int, default 30
        Candidates tried before giving up.

    Returns
    -------
    Step or None
        The first candidate whose objective is ``<= value``; ``None`` when all
        ``max_halvings`` candidates were infeasible or worse.

    Examples
    --------
    A bound stops the step at 2:

    >>> out = safeguarded_step(lambda x: ((x - 3.0) ** 2, None), 0.0, 3.0, 9.0,
    ...                        bounds=(-1.0, 2.0))
    >>> out.x, out.value
    (2.0, 1.0)
    """
    for _ in range(int(max_halvings)):
        cand = x + step
        if bounds is not None:
            lo, hi = bounds
            cand = min(max(cand, lo), hi) if np.ndim(cand) == 0 else np.clip(cand, lo, hi)
        out = objective(cand)
        if out is not None and out[0] <= value:
            return Step(cand, out[0], out[1], step)
        step = 0.5 * step
    return None
