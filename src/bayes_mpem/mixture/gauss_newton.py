"""The safeguard of a Gauss-Newton M-step: halve the step until the objective does not increase."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

#: Halvings tried before a step is given up.
MAX_HALVINGS = 30


class Step(NamedTuple):
    """An accepted step of :func:`safeguarded_step`: ``x``, ``value``, ``aux``, ``step``.

    Attributes
    ----------
    x : float or numpy.ndarray
        The new point (within the bounds).
    value : float
        The objective there (no larger than at the start).
    aux : object
        What the objective returned with its value.
    step : float or numpy.ndarray
        The step taken, before projection into the bounds.
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
        ``objective(x) -> (value, aux)``, or ``None`` where ``x`` is infeasible.
    x, step : float or numpy.ndarray
        The current point and the proposed (Gauss-Newton) step.
    value : float
        The objective at ``x``.
    bounds : tuple of float, optional
        ``(lo, hi)``: every candidate is clipped into them.
    max_halvings : int, default 30

    Returns
    -------
    Step or None
        The first candidate whose objective is ``<= value``; ``None`` when none was.

    Examples
    --------
    >>> out = safeguarded_step(lambda x: ((x - 3.0) ** 2, None), 0.0, 10.0, 9.0)
    >>> out.x, out.value, out.step
    (5.0, 4.0, 5.0)
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
