"""Figures. Every function takes ``ax=`` (or ``fig=``) and returns the Figure.

The class colour follows the paper's Fig. 8: blue = direct path, red =
multipath, green = outlier, mixed by the class probabilities, so a range that
is half direct path, half multipath is drawn purple.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg", force=False)
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .mixture import BeaconGeometry  # noqa: E402


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
    """
    resp = np.asarray(resp, float)
    return np.clip(resp[:, [1, 2, 0]], 0.0, 1.0)


def _ax(ax, figsize=(8, 4)):
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    return ax.figure, ax


def plot_classification(survey_fit, beacon, *, ax=None, resp=None, title=None):
    """Range against time for one beacon, coloured by class probability.

    With the prediction lines of the fitted direct path and multipath (the
    paper's Figs. 7, 9 and 13).

    Parameters
    ----------
    survey_fit : SurveyFit
    beacon : str
    ax : matplotlib.axes.Axes, optional
    resp : array_like, optional
        Probabilities to colour by (default: the final ones; pass
        ``result.first_resp`` for the first iteration).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _ax(ax)
    res = survey_fit.results[beacon]
    data = survey_fit.survey.for_beacon(beacon)
    geom = BeaconGeometry.from_data(data)
    resp = res.resp if resp is None else resp
    ax.scatter(data.time, data.range, c=class_colors(resp), s=4, linewidths=0)
    order = np.argsort(data.time)
    ax.plot(data.time[order], geom.direct[order], color="0.3", lw=0.6, label="direct path")
    ax.plot(data.time[order], geom.multipath(res.d0, res.path)[order], color="0.6", lw=0.6,
            ls="--", label=f"multipath, d0 = {res.d0:.1f} m")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("one-way range (m)")
    ax.set_title(title or f"beacon {beacon}: {res.method} EM, sigma_MP = {res.sigma_mp:.2f} m")
    ax.legend(loc="upper right", fontsize="small")
    return fig


def plot_survey_classification(survey_fit, *, fig=None):
    """Every beacon's classification in one figure (the paper's Fig. 13).

    Parameters
    ----------
    survey_fit : SurveyFit
    fig : matplotlib.figure.Figure, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    ids = list(survey_fit.results)
    if fig is None:
        fig = plt.figure(figsize=(10, 2.6 * max(len(ids), 1)), layout="constrained")
    axes = fig.subplots(max(len(ids), 1), 1, squeeze=False, sharex=True)[:, 0]
    for ax, bid in zip(axes, ids, strict=False):
        plot_classification(survey_fit, bid, ax=ax)
    return fig


def plot_track(survey, *, ax=None):
    """Vehicle track in the x-y plane with the beacons (the paper's Fig. 5).

    Parameters
    ----------
    survey : Survey
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _ax(ax, figsize=(6, 6))
    ax.plot(survey.x, survey.y, ".", ms=1.5, color="0.4", label="vehicle")
    b = survey.beacons
    ax.plot(b["x"], b["y"], "s", color="tab:red", label="beacons")
    for bid, row in b.iterrows():
        ax.annotate(f" {bid}", (row["x"], row["y"]), color="tab:red")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize="small")
    return fig
