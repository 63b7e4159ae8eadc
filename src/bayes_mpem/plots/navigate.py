"""Figures of a navigated dive (:class:`~bayes_mpem.lbl.navigate.Navigation`)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import EllipseCollection

from .style import class_colors

#: 95 % quantile of the chi-square distribution with 2 degrees of freedom.
CHI2_95 = 5.991


def _ax(ax, figsize):
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    return ax.figure, ax


def ellipse_axes(cov, *, q=CHI2_95):
    """Full widths, heights (m) and angles (degrees) of the ``q``-level ellipses of 2x2 covariances.

    Parameters
    ----------
    cov : numpy.ndarray
        ``(K, 2, 2)``.
    q : float
        Chi-square quantile (default: 95 % with 2 degrees of freedom).
    """
    vals, vecs = np.linalg.eigh(cov)
    w = 2.0 * np.sqrt(np.maximum(vals[:, 1], 0.0) * q)
    h = 2.0 * np.sqrt(np.maximum(vals[:, 0], 0.0) * q)
    ang = np.degrees(np.arctan2(vecs[:, 1, 1], vecs[:, 0, 1]))
    return w, h, ang


def _magnification(size, target):
    """Return a round factor (1, 2 or 5 times a power of 10) taking ``size`` up to ``target``."""
    if not size > 0 or size >= target:
        return 1.0
    ratio = target / size
    base = 10.0 ** np.floor(np.log10(ratio))
    return float(max(m * base for m in (1.0, 2.0, 5.0) if m * base <= ratio))


def plot_nav_track(nav, *, truth=None, ax=None, n_ellipses=40):
    """Draw the corrected track over the dead reckoning, with 95 % error ellipses, and the beacons.

    Parameters
    ----------
    truth : pandas.DataFrame, optional
        ``x``, ``y`` of the true track.
    """
    fig, ax = _ax(ax, (7, 6))
    d = nav.dive
    ax.plot(d.dr[:, 0], d.dr[:, 1], color="0.6", lw=0.8, ls="--", label="dead reckoning")
    if truth is not None:
        ax.plot(truth["x"], truth["y"], color="k", lw=0.6, label="truth")
    ax.plot(nav.track[:, 0], nav.track[:, 1], color="tab:blue", lw=0.9, label="navigated")
    idx = np.unique(np.linspace(0, d.n_epochs - 1, max(int(n_ellipses), 1)).astype(int))
    w, h, ang = ellipse_axes(nav.cov[idx])
    span = float(np.ptp(np.concatenate([nav.track, d.dr]), axis=0).max()) or 1.0
    mag = _magnification(float(np.median(w)), 0.04 * span)
    ax.add_collection(EllipseCollection(w * mag, h * mag, ang, units="xy",
                                        offsets=nav.track[idx], offset_transform=ax.transData,
                                        facecolors="none", edgecolors="tab:orange", lw=0.8))
    ax.plot([], [], color="tab:orange", lw=0.8,
            label="95 % ellipses" + (f" (x{mag:g})" if mag > 1 else ""))
    xyz = d.beacon_xyz
    ax.scatter(xyz[:, 0], xyz[:, 1], marker="^", color="k", s=40, zorder=3)
    for bid, (x, y) in zip(d.beacon_ids, xyz[:, :2], strict=True):
        ax.annotate(bid, (x, y), xytext=(4, 4), textcoords="offset points")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize="small")
    ax.set_title("navigated track", fontsize="medium")
    return fig


def plot_nav_ranges(nav, *, fig=None):
    """Range against time for every beacon, coloured by class (blue dp, red mp, green ol)."""
    d = nav.dive
    shown = [j for j, b in enumerate(d.beacon_ids) if b not in nav.skipped]
    if fig is None:
        fig = plt.figure(figsize=(8, 1.8 + 1.6 * len(shown)), layout="constrained")
    axes = fig.subplots(len(shown), 1, sharex=True, squeeze=False)[:, 0]
    t = d.times[d.epoch]
    for ax, j in zip(axes, shown, strict=True):
        m = d.beacon == j
        ax.scatter(t[m], d.z[m], c=class_colors(nav.resp[m]), s=3, linewidths=0)
        ax.set_ylabel(f"beacon {d.beacon_ids[j]}\nrange (m)")
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title("replies by class (blue direct path, red multipath, green outlier)",
                      fontsize="medium")
    return fig


def plot_nav_correction(nav, *, truth=None, fig=None):
    """Draw the correction (navigated minus dead-reckoned position) against time, with +-2 sd.

    Parameters
    ----------
    truth : pandas.DataFrame, optional
        ``x``, ``y`` of the true track: the dead reckoning's true error is drawn too.
    """
    if fig is None:
        fig = plt.figure(figsize=(8, 4.5), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    d = nav.dive
    for k, (ax, name) in enumerate(zip(axes, ("x", "y"), strict=True)):
        corr = nav.track[:, k] - d.dr[:, k]
        sd = np.sqrt(nav.cov[:, k, k])
        ax.fill_between(d.times, corr - 2 * sd, corr + 2 * sd, color="tab:blue", alpha=0.25,
                        lw=0, label="+-2 sd")
        ax.plot(d.times, corr, color="tab:blue", lw=0.8, label="navigated - dead reckoning")
        if truth is not None:
            ax.plot(d.times, np.asarray(truth[name]) - d.dr[:, k], color="k", lw=0.6,
                    label="truth - dead reckoning")
        ax.set_ylabel(f"{name} correction (m)")
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time (s)")
    return fig
