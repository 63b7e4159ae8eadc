"""Random-number-generator normalisation shared by every seeded function."""

from __future__ import annotations

import numpy as np

RNGLike = None | int | np.random.Generator


def as_generator(rng: RNGLike) -> np.random.Generator:
    """Return a :class:`numpy.random.Generator` for ``rng``.

    Parameters
    ----------
    rng : None, int or numpy.random.Generator
        ``None`` gives fresh OS entropy, an int is a seed, a Generator is
        returned unchanged (so callers can share one stream).

    Raises
    ------
    TypeError
        If ``rng`` is of any other type.
    ValueError
        For a negative seed.
    """
    if rng is None or isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        if rng is not None and rng < 0:
            raise ValueError(f"rng: expected a non-negative integer seed, got {rng!r}")
        return np.random.default_rng(rng)
    if isinstance(rng, np.random.Generator):
        return rng
    raise TypeError(
        f"rng: expected None, an int seed or a numpy.random.Generator, got {type(rng).__name__}"
    )
