"""The class colours shared by every figure (the paper's three-value colour map).

Blue is direct path, red multipath, green outlier; a range's colour mixes
them by its class probabilities (:func:`class_colors`). The survey-in figures
colour a ping true or spurious (:data:`SURVEY_IN_COLORS`, colour-blind safe,
with a marker per class: :data:`SURVEY_IN_MARKERS`).
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


#: Colours of a survey-in's ping classes (Okabe-Ito blue and vermillion: told apart with
#: every common colour-vision deficiency), and of lines that were not pings.
SURVEY_IN_COLORS = {"true": "#0072B2", "spurious": "#D55E00", "skipped": "#999999"}
#: Markers of the same classes, so that the figures read in grey too.
SURVEY_IN_MARKERS = {"true": "o", "spurious": "X", "skipped": "."}
