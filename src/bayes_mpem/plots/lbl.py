"""Figures. Every function takes ``ax=`` (or ``fig=``) and returns the Figure."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from .._validate import check_choice
from ..lbl.model.beacon_geometry import BeaconGeometry
from .style import CLASS_NAMES, PARAM_LABELS, class_color, class_colors, class_key, plain_log_axis


def _ax(ax, figsize=(8, 4)):
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    return ax.figure, ax


def plot_classification(survey_fit, beacon, *, ax=None, iteration="last", lines=True,
                        title=None, key=True):
    """Range against time for one beacon, coloured by class probability.

    Parameters
    ----------
    survey_fit : SurveyFit
    beacon : str
    ax : matplotlib.axes.Axes, optional
    iteration : {"last", "first"}
        Colour by the final class probabilities or by those of the first E-step.
    lines : bool, default True
        Draw the predicted direct path and multipath.
    title : str, optional
    key : bool, default True
        Add the legend.

    Returns
    -------
    matplotlib.figure.Figure
    """
    check_choice("iteration", iteration, ("first", "last"), words=True)
    fig, ax = _ax(ax)
    res = survey_fit.results[beacon]
    data = survey_fit.survey.for_beacon(beacon)
    resp = res.first_resp if iteration == "first" else res.resp
    ax.scatter(data.time, data.range, c=class_colors(resp), s=4, linewidths=0)
    if lines:
        geom = BeaconGeometry.from_data(data)
        d0 = res.history["d0"][0] if iteration == "first" else res.d0
        order = np.argsort(data.time)
        # under the ranges (zorder), so the class colours stay visible
        ax.plot(data.time[order], geom.direct[order], color="k", lw=0.6, alpha=0.6,
                label="predicted direct path", zorder=0.8)
        ax.plot(data.time[order], geom.multipath(d0, res.path)[order], color="k", lw=0.6,
                ls="--", alpha=0.6, label=f"predicted {res.path} multipath", zorder=0.8)
    if key:
        # beside the panel, where it hides no range
        class_key(ax, extra=ax.get_lines(), where="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("one-way range (m)")
    if title is None:
        if iteration == "first":
            s0 = res.history["sigma_mp"][0]
            title = (f"beacon {beacon}: {res.method} EM, first E-step "
                     f"(d0 = {res.history['d0'][0]:.0f} m, sigma_MP = {s0:.0f} m)")
        else:
            title = (f"beacon {beacon}: {res.method} EM, last iteration ({res.n_iter}): "
                     f"d0 = {res.d0:.1f} m, sigma_MP = {res.sigma_mp:.2f} m")
    ax.set_title(title, fontsize="medium")
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
        fig = plt.figure(figsize=(10, 2.6 * max(len(ids), 1) + 0.4), layout="constrained")
    axes = fig.subplots(max(len(ids), 1), 1, squeeze=False, sharex=True)[:, 0]
    for ax, bid in zip(axes, ids, strict=False):
        plot_classification(survey_fit, bid, ax=ax, key=False)
        ax.label_outer()
    class_key(fig, extra=axes[0].get_lines())
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
    fig, ax = _ax(ax, figsize=(6, 4.5))
    ax.plot(survey.x, survey.y, "-", lw=0.8, color="0.4", label="vehicle")
    b = survey.beacons
    ax.plot(b["x"], b["y"], "s", color="k", label="beacons")
    for bid, row in b.iterrows():
        ax.annotate(f" beacon {bid}", (row["x"], row["y"]), color="k", fontsize="small")
    ax.set_aspect("equal")
    ax.margins(0.12)  # room for the beacons' names
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize="small")
    return fig


def plot_ranges(survey, *, ax=None):
    """Range against time for every beacon, coloured by beacon (the paper's Fig. 1).

    Parameters
    ----------
    survey : Survey
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _ax(ax, figsize=(10, 4))
    for i, bid in enumerate(survey.beacon_ids):
        m = (survey.beacon == bid) & ~survey.no_reply
        ax.plot(survey.time[m], survey.range[m], ".", ms=2, color=f"C{i}",
                label=f"beacon {bid}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("one-way range (m)")
    ax.legend(loc="upper right", markerscale=5, fontsize="small")
    ax.set_title("LBL ranges by beacon")
    return fig


def plot_colormap(*, ax=None, resolution=400):
    """Draw the three-value colour map of class probabilities (the paper's Fig. 8).

    Parameters
    ----------
    ax : matplotlib.axes.Axes, optional
    resolution : int, default 400
        Pixels along each side.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _ax(ax, figsize=(5, 4.6))
    h = np.sqrt(3) / 2
    x, y = np.meshgrid(np.linspace(0, 1, resolution), np.linspace(0, h, resolution))
    p_ol = y / h
    p_mp = x - 0.5 * p_ol
    p_dp = 1.0 - p_mp - p_ol
    probs = np.stack([p_dp, p_mp, p_ol], axis=-1)
    inside = np.all(probs >= -1e-9, axis=-1)
    rgba = np.zeros((*x.shape, 4))
    rgba[..., :3] = class_colors(np.clip(probs, 0, 1).reshape(-1, 3)).reshape(*x.shape, 3)
    rgba[..., 3] = inside
    ax.imshow(rgba, origin="lower", extent=(0, 1, 0, h), interpolation="bilinear")
    ax.plot([0, 1, 0.5, 0], [0, 0, h, 0], color="k", lw=0.8)
    for (px, py), text, va in (((0, 0), "direct path", "top"), ((1, 0), "multipath", "top"),
                               ((0.5, h), "outlier", "bottom")):
        ax.annotate(text, (px, py), ha="center", va=va, xytext=(0, -6 if va == "top" else 6),
                    textcoords="offset points")
    ax.set_xlim(-0.12, 1.12)
    ax.set_ylim(-0.1, h + 0.1)
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.set_title("class probability colour map")
    return fig


def plot_convergence(result, *, fig=None, truth=None):
    """d0 and sigma_MP over the EM iterations (the paper's Figs. 10 and 11).

    Parameters
    ----------
    result : EMResult
    fig : matplotlib.figure.Figure, optional
    truth : dict, optional
        ``{"d0": .., "sigma_mp": ..}`` drawn as dashed lines.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if fig is None:
        fig = plt.figure(figsize=(9, 3.4), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    it = np.arange(len(result.history["d0"]))
    ax1.plot(it, result.history["d0"], ".-", color="k")
    ax1.set_ylabel(PARAM_LABELS["d0"])
    ax1.set_title("d0: height of the reflecting plane above the beacon", fontsize="medium")
    ax2.semilogy(it, result.history["sigma_mp"], ".-", color="k")
    plain_log_axis(ax2.yaxis)
    ax2.set_ylabel(PARAM_LABELS["sigma_mp"])
    ax2.set_title("sigma_MP: multipath scatter", fontsize="medium")
    for ax, key in ((ax1, "d0"), (ax2, "sigma_mp")):
        ax.set_xlabel("iteration")
        if truth is not None and key in truth:
            ax.axhline(truth[key], color="0.4", ls="--", lw=0.8, label="truth")
            ax.legend(fontsize="small")
    fig.suptitle(f"beacon {result.beacon}: convergence of the {result.method} EM")
    return fig


def plot_pol_sensitivity(sens, *, fig=None, truth=None):
    """d0, sigma_MP and mean class probabilities against ``Pol`` (the paper's Fig. 12).

    Parameters
    ----------
    sens : dict
        From :func:`pol_sensitivity`.
    fig : matplotlib.figure.Figure, optional
    truth : dict, optional
        ``{"d0": .., "sigma_mp": .., "weights": {..}}`` drawn as dashed lines.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if fig is None:
        fig = plt.figure(figsize=(11, 3.4), layout="constrained")
    a, b, c = fig.subplots(1, 3)
    a.plot(sens["pol"], sens["d0"], "o-", color="k")
    mid = float(np.median(sens["d0"]))
    lo, hi = min(np.min(sens["d0"]), mid - 10.0), max(np.max(sens["d0"]), mid + 10.0)
    a.set_ylim(lo - 1.0, hi + 1.0)  # at least 20 m: a 2 m wobble should look like one
    a.set_ylabel(PARAM_LABELS["d0"])
    a.set_title("a: plane height d0", loc="left")
    b.plot(sens["pol"], sens["sigma_mp"], "o-", color="k")
    b.set_ylabel(PARAM_LABELS["sigma_mp"])
    b.set_title("b: multipath scatter", loc="left")
    for cls in ("dp", "mp", "ol"):
        c.plot(sens["pol"], sens["p_" + cls], "o-", color=class_color(cls),
               label=CLASS_NAMES[cls])
    c.set_ylabel("mean class probability")
    c.set_ylim(0, 1)
    c.set_title("c: class probabilities", loc="left")
    c.legend(fontsize="small")
    if truth is not None:
        a.axhline(truth["d0"], color="0.4", ls="--", lw=0.8, label="truth")
        b.axhline(truth["sigma_mp"], color="0.4", ls="--", lw=0.8, label="truth")
        for cls in ("dp", "mp", "ol"):
            c.axhline(truth["weights"][cls], color=class_color(cls), ls=":", lw=0.8)
        a.legend(fontsize="small")
    for ax in (a, b, c):
        ax.set_xlabel("Pol")
    fig.suptitle("Sensitivity of the paper's EM to Pol")
    return fig


def table_ii_markdown(survey_fit, *, truth=None) -> str:
    """Format the per-beacon results as a Markdown table laid out as the paper's Table II.

    Parameters
    ----------
    survey_fit : SurveyFit
    truth : dict, optional
        ``Simulation.truth``: adds the true sigma_MP.
    """
    t = survey_fit.table()
    head = "| | " + " | ".join(f"beacon {b}" for b in t["beacon"]) + " |"
    rows = [head, "|---|" + "---:|" * len(t),
            "| d0 (m) | " + " | ".join(f"{v:.1f}" for v in t["d0_m"]) + " |",
            "| sigma_MP (m) | " + " | ".join(f"{v:.2f}" for v in t["sigma_mp_m"]) + " |"]
    if truth is not None:
        rows.append("| true sigma_MP (m) | " + " | ".join(
            f"{truth[b]['sigma_mp']:.2f}" for b in t["beacon"]) + " |")
    rows += ["| beacon depth (m) | " + " | ".join(f"{v:.1f}" for v in t["beacon_depth_m"])
             + " |",
             "| fraction DP / MP / OL | " + " | ".join(
                 f"{r.dp:.2f} / {r.mp:.2f} / {r.ol:.2f}" for r in t.itertuples()) + " |"]
    return "\n".join(rows)


def plot_table_ii(survey_fit, *, ax=None):
    """Table II as a figure: fitted plane heights and sigma_MP beside the beacon depths.

    Parameters
    ----------
    survey_fit : SurveyFit
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _ax(ax, figsize=(7, 1.8))
    t = survey_fit.table()
    cells = [[f"{v:.1f}" for v in t["d0_m"]], [f"{v:.2f}" for v in t["sigma_mp_m"]],
             [f"{v:.1f}" for v in t["beacon_depth_m"]]]
    ax.table(cellText=cells, rowLabels=["d0 (m)", "sigma_MP (m)", "beacon depth (m)"],
             colLabels=[f"beacon {b}" for b in t["beacon"]], loc="center", cellLoc="center")
    ax.set_axis_off()
    ax.set_title(f"Multipath identification results ({survey_fit.method} EM)")
    return fig
