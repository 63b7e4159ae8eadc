"""The class colours shared by every figure (the paper's three-value colour map).

Blue is direct path, red multipath, green outlier; a range's colour mixes
them by its class probabilities (:func:`class_colors`).
"""

from __future__ import annotations

import numpy as np


def class_colors(resp):
    """RGB colours of class probabilities (the paper's three-value colour map).

    Parameters
    ----------
    resp : array_like
        ``(n, 3)`` probabilities of dp, mp, ol.

    Returns
    -------
    numpy.ndarray
        ``(n, 3)`` RGB in [0, 1]: red = p_mp, green = p_ol, blue = p_dp.

    Examples
    --------
    >>> class_colors([[1.0, 0.0, 0.0]]).tolist()
    [[0.0, 0.0, 1.0]]
    """
    resp = np.asarray(resp, float)
    return np.clip(resp[:, [1, 2, 0]], 0.0, 1.0)
