"""Figures of a located survey (``bayes-mpem locate``): the map and the residuals."""

from __future__ import annotations

import textwrap

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Ellipse
from matplotlib.ticker import MaxNLocator
from scipy.stats import chi2

from .style import SURVEY_IN_COLORS, SURVEY_IN_MARKERS


def _cov2(t):
    """East-north covariance of a transponder's summary entry (EM's, or from the sds)."""
    for entry in (t, t.get("em", {})):
        if "covariance" in entry:
            return np.asarray(entry["covariance"]["matrix"], float)[:2, :2]
    return np.diag([t["east"]["sd"] ** 2, t["north"]["sd"] ** 2])


def _ellipse(ax, centre, cov, ci, **kw):
    """Draw the ``ci`` region of a 2-D Gaussian; return its semi-major axis (m)."""
    vals, vecs = np.linalg.eigh(cov)
    vals = np.clip(vals, 0.0, None)
    k = np.sqrt(chi2.ppf(ci, 2))
    angle = np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1]))
    ax.add_patch(Ellipse(centre, 2 * k * np.sqrt(vals[1]), 2 * k * np.sqrt(vals[0]),
                         angle=angle, fill=False, **kw))
    return float(k * np.sqrt(vals[1]))


def _anchor(summary, tid):
    """Return what a solution is compared with: an array's prior, or the drop point (0, 0)."""
    t = summary["transponders"][tid]
    if "prior" in t:
        return np.array([t["prior"]["east"], t["prior"]["north"]]), "prior position"
    if "drop_point" in summary:
        return np.zeros(2), "drop point"
    return None, None


def plot_survey_map(result, *, fig=None):
    """Track, drop point (or prior positions), solutions with ellipses, and close-ups."""
    s, cls = result.summary, result.classified
    tids = list(s["transponders"])
    ncol = int(np.ceil(np.sqrt(len(tids))))
    nrow = int(np.ceil(len(tids) / ncol))
    if fig is None:
        fig = plt.figure(figsize=(6.0 + 3.2 * ncol, max(5.2, 2.8 * nrow)), layout="constrained")
    gs = fig.add_gridspec(nrow, 2 + ncol, width_ratios=[1.6, 1.6] + [1.0] * ncol)
    ax = fig.add_subplot(gs[:, :2])
    pinged = cls[cls["label"] != "skipped"].sort_values("time", kind="stable")
    ax.plot(pinged["east"], pinged["north"], "-", color="0.6", lw=0.8, label="ship's track")
    for j, tid in enumerate(tids):
        t = s["transponders"][tid]
        e, n = t["east"]["mean"], t["north"]["mean"]
        ax.plot(e, n, "*", color="k", ms=11, label="solution" if j == 0 else None)
        ax.annotate(tid, (e, n), textcoords="offset points", xytext=(6, 6))
        anchor, name = _anchor(s, tid)
        if anchor is not None:
            ax.plot(*anchor, "^", color=SURVEY_IN_COLORS["spurious"], ms=8, mfc="none",
                    label=name if j == 0 else None)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.legend(loc="best", fontsize="small")
    for j, tid in enumerate(tids):
        t = s["transponders"][tid]
        r, c = divmod(j, ncol)
        _closeup(fig.add_subplot(gs[r, 2 + c]), s, tid, t)
    ci = next(iter(s["transponders"].values())).get("ci", 0.95)
    fig.suptitle(f"Location: solutions with their {100 * ci:g} % ellipses")
    return fig


def _closeup(ax, s, tid, t):
    e, n = t["east"]["mean"], t["north"]["mean"]
    ci = t.get("ci", 0.95)
    half = max(4.0 * _ellipse(ax, (e, n), _cov2(t), ci, color="k", lw=1.2,
                              label=f"{100 * ci:g} % ellipse"), 0.05)
    ax.plot(e, n, "*", color="k", ms=10)
    anchor, name = _anchor(s, tid)
    if anchor is not None:
        d = anchor - np.array([e, n])
        dist = float(np.hypot(*d))
        if dist <= half:
            ax.plot(*anchor, "^", color=SURVEY_IN_COLORS["spurious"], mfc="none", ms=8,
                    label=name)
        else:
            u = d / dist
            ax.annotate("", xy=(e + 0.9 * half * u[0], n + 0.9 * half * u[1]), xytext=(e, n),
                        arrowprops={"arrowstyle": "->", "color": SURVEY_IN_COLORS["spurious"]})
            ax.text(0.03, 0.93, f"{name} {dist:.2f} m away", transform=ax.transAxes,
                    fontsize="x-small", color=SURVEY_IN_COLORS["spurious"])
    if "drift" in t:
        ax.text(0.03, 0.85, f"drift {t['drift']['mean']:.2f} m, az {t['azimuth']['mean']:.1f} "
                "deg", transform=ax.transAxes, fontsize="x-small")
    ax.set_xlim(e - half, e + half)
    ax.set_ylim(n - half, n + half)
    ax.set_aspect("equal")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(MaxNLocator(3))
    ax.ticklabel_format(useOffset=False)
    ax.tick_params(labelsize="x-small")
    ax.set_title(f"{tid}", fontsize="small")
    ax.legend(loc="lower right", fontsize="x-small")


def _pinged(result):
    """Return the pings classified (not skipped), the residual axis limit and sigma (ms)."""
    cls = result.classified
    cls = cls[cls["label"].isin(["true", "spurious"])]
    true = cls.loc[cls["label"] == "true", "residual_ms"].to_numpy(float)
    sig = float(np.median([t["sigma_ms"] if not isinstance(t["sigma_ms"], dict)
                           else t["sigma_ms"]["mean"]
                           for t in result.summary["transponders"].values()]))
    top = np.nanmax(np.abs(true)) if true.size else 1.0
    return cls, float(max(5.0 * sig, 1.1 * top)), sig


def _scatter_classes(ax, cls, x, lim, *, key=True):
    n_out = 0
    for lab in ("true", "spurious"):
        sub = cls[cls["label"] == lab]
        y = sub["residual_ms"].to_numpy(float)
        out = np.abs(y) > lim
        n_out += int(out.sum())
        ax.scatter(sub[x], np.clip(y, -lim, lim), s=9 if lab == "true" else 22,
                   c=SURVEY_IN_COLORS[lab], marker=SURVEY_IN_MARKERS[lab], linewidths=0,
                   alpha=0.7 if lab == "true" else 0.9,
                   label=f"{lab} ({len(sub)})" if key else None)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_ylim(-1.05 * lim, 1.05 * lim)
    return n_out


def plot_residuals(result, *, fig=None):
    """Residuals (observed minus predicted two-way travel time) against time and azimuth."""
    cls, lim, _ = _pinged(result)
    if fig is None:
        fig = plt.figure(figsize=(11, 4.2), layout="constrained")
    a1, a2 = fig.subplots(1, 2, sharey=True)
    n_out = _scatter_classes(a1, cls, "time", lim)
    _scatter_classes(a2, cls, "azimuth_deg", lim, key=False)
    a1.set_xlabel("time (s)")
    a2.set_xlabel("azimuth of the ship from the transponder (deg)")
    a2.set_xlim(0, 360)
    a2.set_xticks(np.arange(0, 361, 90))
    a1.set_ylabel("residual (ms)")
    a1.legend(title="class", fontsize="small", loc="upper right")
    fig.suptitle("Travel-time residuals by class"
                 + (f" ({n_out} beyond +-{lim:.3g} ms drawn at the edge)" if n_out else ""))
    return fig


def plot_residual_histogram(result, *, fig=None):
    """Histogram of the residuals by class, with the fitted Gaussian of the true pings."""
    cls, lim, sig = _pinged(result)
    if fig is None:
        fig = plt.figure(figsize=(6.5, 4.2), layout="constrained")
    ax = fig.subplots()
    bins = np.linspace(-lim, lim, int(np.clip(2 * np.sqrt(len(cls)), 12, 80)) + 1)
    data = [np.clip(cls.loc[cls["label"] == lab, "residual_ms"].to_numpy(float), -lim, lim)
            for lab in ("true", "spurious")]
    ax.hist(data, bins=bins, stacked=True, color=[SURVEY_IN_COLORS[k] for k in
                                                  ("true", "spurious")],
            label=[f"{k} ({len(v)})" for k, v in zip(("true", "spurious"), data, strict=True)])
    x = np.linspace(-lim, lim, 400)
    width = bins[1] - bins[0]
    ax.plot(x, len(data[0]) * width * np.exp(-0.5 * (x / sig) ** 2) / (sig * np.sqrt(2 * np.pi)),
            color="k", lw=1.2, label=f"N(0, {sig:.3g} ms)")
    ax.set_xlabel("residual (ms; spurious beyond the axis in the end bins)")
    ax.set_ylabel("pings")
    ax.legend(title="class", fontsize="small")
    ax.set_title("Residual histogram")
    return fig


# ------------------------------------------------------------------ arrays (GNSS-A)


def _ci(summary):
    """Return the interval probability of a summary (its transponders')."""
    return next(iter(summary["transponders"].values())).get("ci", 0.95)


def plot_sound_speed(result, *, ax=None, truth=None):
    """Plot the array's fitted sound speed against time, with its ``ci`` band.

    Parameters
    ----------
    result : SurveyInResult
        An array's (without a series: the survey's one value and its interval).
    truth : dict, optional
        A simulated campaign's ``truth.json``: its change of the depth-averaged speed is
        drawn too (:func:`~bayes_mpem.survey_in.gnssa_simulate.true_speed_change`), about
        the fit's reference (the profile's mean speed) where there is one.
    """
    from scipy.stats import norm

    if ax is None:
        _, ax = plt.subplots(figsize=(8.5, 3.8), layout="constrained")
    ss = result.summary["sound_speed"]
    ci = _ci(result.summary)
    z = float(norm.ppf(0.5 + ci / 2))
    ser = ss.get("series")
    if ser:
        t = np.asarray(ser["time_s"], float) / 3600.0
        m, sd = np.asarray(ser["mean_m_s"], float), np.asarray(ser["sd_m_s"], float)
    else:
        t = np.array([0.0, 1.0])
        m, sd = np.full(2, ss["mean"]), np.full(2, ss["sd"])
    ax.fill_between(t, m - z * sd, m + z * sd, color=SURVEY_IN_COLORS["true"], alpha=0.25,
                    lw=0, label=f"{100 * ci:g} % band")
    ax.plot(t, m, color=SURVEY_IN_COLORS["true"], lw=1.5, label="fitted")
    if ss.get("reference_m_s") is not None:
        ax.axhline(ss["reference_m_s"], color="0.4", lw=0.8, ls="--",
                   label="the survey's profile")
    if truth is not None:
        # the true change of the depth-averaged speed, about the profile the fit used (the
        # two references average the profile over slightly different depths) and the points
        # its gradient terms are about
        from ..survey_in.gnssa_simulate import true_speed_change

        ts = truth["sound_speed"]
        ref = ss.get("reference_m_s")
        tt = np.asarray(ts["series"]["time_s"], float)
        origins = (result.summary.get("gradients") or {}).get("origins_m")
        ax.plot(tt / 3600.0, (ts["reference_m_s"] if ref is None else ref)
                + true_speed_change(truth, tt, origins),
                color="k", lw=1.0, ls=":", label="truth (the depth-averaged change)")
    ax.set_xlabel("time since the first shot (h)" if ser else "(one value for the survey)")
    ax.set_ylabel(f"sound speed ({ss.get('unit', 'm/s')})")
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.legend(fontsize="small", loc="best")
    ax.set_title(textwrap.fill(f"Sound speed: {ss.get('model', '')}", 90), fontsize="medium")
    return ax.figure


#: the gradient terms drawn by :func:`plot_gradients`: (title, summary name, truth key) per
#: panel, east then north
_GRADIENT_PANELS = (
    ("shallow (felt along the ray near the surface: the ship's offset)",
     (("east", "shallow_east", "grad1_east"), ("north", "shallow_north", "grad1_north"))),
    ("deep (across the array: the transponder's offset)",
     (("east", "deep_east", "grad2_east"), ("north", "deep_north", "grad2_north"))))


def plot_gradients(result, *, fig=None, truth=None):
    """Plot the array's horizontal sound-speed gradients against time, with ``ci`` bands.

    GARPOS's shallow and deep terms (``a V0``, (m/s)/km), east and north, from
    ``summary.json``'s ``gradients["series"]`` (the EM's, also after ``--sample``); one
    panel per term fitted (the shallow one only on a circle about the array).

    Parameters
    ----------
    result : SurveyInResult
        An array's, with the gradients fitted.
    fig : matplotlib.figure.Figure, optional
        Drawn into (an axis per term is added); default a new figure.
    truth : dict, optional
        A simulated campaign's ``truth.json``: its gradient series are drawn too.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        Where the summary has no gradient series (not fitted).
    """
    from scipy.stats import norm

    g = result.summary.get("gradients") or {}
    ser = g.get("series")
    if not ser:
        raise ValueError(f"gradients: not fitted ({g.get('reason', 'no gradients entry')}); "
                         "nothing to plot")
    panels = [p for p in _GRADIENT_PANELS if p[1][0][1] in ser]
    if fig is None:
        fig = plt.figure(figsize=(10.5, 0.8 + 2.4 * len(panels)), layout="constrained")
    ci = _ci(result.summary)
    z = float(norm.ppf(0.5 + ci / 2))
    t = np.asarray(ser["time_s"], float) / 3600.0
    tg = (truth or {}).get("gradients")
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    for ax, (title, terms) in zip(axes, panels, strict=True):
        for (axis, name, key), color in zip(terms, ("C0", "C3"), strict=True):
            m, sd = np.asarray(ser[name]["mean"], float), np.asarray(ser[name]["sd"], float)
            ax.fill_between(t, m - z * sd, m + z * sd, color=color, alpha=0.2, lw=0)
            avg = g[name].get("em") or g[name]  # the EM's, as the series (after --sample too)
            ax.plot(t, m, color=color, lw=1.5,
                    label=f"{axis} (average {avg['mean']:+.3f} +- {avg['sd']:.3f})")
            if tg is not None:
                ax.plot(np.asarray(tg["time_s"], float) / 3600.0, tg[key], color=color,
                        lw=1.0, ls=":", label=f"{axis}, truth")
        ax.axhline(0.0, color="0.4", lw=0.6)
        ax.set_ylabel(f"{g.get('unit', '(m/s)/km')}")
        ax.set_title(title, fontsize="medium")
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set_xlabel("time since the first shot (h)")
    fig.suptitle(f"Horizontal sound-speed gradients (GARPOS's gradV), {100 * ci:g} % bands")
    return fig


def plot_residuals_by_transponder(result, *, fig=None):
    """Residuals against time, one panel per transponder, by class."""
    cls, lim, _ = _pinged(result)
    tids = [t for t in result.summary["transponders"]]
    if fig is None:
        fig = plt.figure(figsize=(10, 1.9 + 1.7 * len(tids)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(tids), 1, sharex=True, sharey=True))
    t0 = float(cls["time"].min()) if len(cls) else 0.0
    cls = cls.assign(hours=(cls["time"] - t0) / 3600.0)
    n_out = 0
    for j, (ax, tid) in enumerate(zip(axes, tids, strict=True)):
        sub = cls[cls["transponder"].astype(str) == str(tid)]
        n_out += _scatter_classes(ax, sub, "hours", lim, key=True)
        true = sub.loc[sub["label"] == "true", "residual_ms"].to_numpy(float)
        rms = float(np.sqrt(np.mean(true**2))) if true.size else float("nan")
        ax.text(0.01, 0.9, f"{tid}: rms {rms:.3g} ms", transform=ax.transAxes,
                fontsize="small", va="top")
        ax.set_ylabel("ms")
        ax.legend(fontsize="x-small", loc="upper right", ncols=2)
        if j == len(tids) - 1:
            ax.set_xlabel("time since the first shot (h)")
    fig.suptitle("Residuals per transponder (observed minus predicted two-way time)"
                 + (f"; {n_out} beyond +-{lim:.3g} ms drawn at the edge" if n_out else ""))
    return fig


def _offset_panel(ax, name, delta_cm, cov_cm, up_cm, up_sd_cm, ci, true_cm=None):
    """Draw one position against its prior, in cm: the solution, its ellipse, the prior."""
    semi = _ellipse(ax, delta_cm, cov_cm, ci, color="k", lw=1.2,
                    label=f"{100 * ci:g} % ellipse")
    ax.plot(*delta_cm, "*", color="k", ms=10, label="solution")
    half = max(3.0 * semi, 1.0)
    dist = float(np.hypot(*delta_cm))
    if dist <= half:
        ax.plot(0.0, 0.0, "^", color=SURVEY_IN_COLORS["spurious"], mfc="none", ms=8,
                label="prior")
    else:
        ax.text(0.03, 0.04, f"prior {dist / 100:.2f} m away", transform=ax.transAxes,
                fontsize="x-small", color=SURVEY_IN_COLORS["spurious"])
    if true_cm is not None:
        ax.plot(*true_cm[:2], "o", color="k", mfc="none", ms=7,
                label=f"truth (up {true_cm[2]:+.1f})")
        ax.legend(fontsize="xx-small", loc="upper right")
    ax.set_xlim(delta_cm[0] - half, delta_cm[0] + half)
    ax.set_ylim(delta_cm[1] - half, delta_cm[1] + half)
    ax.set_aspect("equal")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax.tick_params(labelsize="x-small")
    ax.set_title(f"{name}: up {up_cm:+.1f} cm (sd {up_sd_cm:.1f})", fontsize="small")
    ax.set_xlabel("east - prior (cm)", fontsize="x-small")
    ax.set_ylabel("north - prior (cm)", fontsize="x-small")


def plot_array_map(result, *, fig=None, truth=None):
    """Plot the array: track and positions (m), each position minus its prior (cm, with ellipse).

    Parameters
    ----------
    result : SurveyInResult
        An array's.
    truth : dict, optional
        A simulated campaign's ``truth.json``: the true positions are marked.
    """
    s, cls = result.summary, result.classified
    tids = list(s["transponders"])
    ci = _ci(s)
    n = len(tids) + 1
    ncol = int(np.ceil(np.sqrt(n)))
    nrow = int(np.ceil(n / ncol))
    if fig is None:
        fig = plt.figure(figsize=(6.0 + 3.0 * ncol, max(5.5, 3.0 * nrow)), layout="constrained")
    gs = fig.add_gridspec(nrow, 2 + ncol, width_ratios=[1.6, 1.6] + [1.0] * ncol)
    ax = fig.add_subplot(gs[:, :2])
    pinged = cls[cls["label"] != "skipped"].sort_values("time", kind="stable")
    ax.plot(pinged["east"], pinged["north"], "-", color="0.7", lw=0.6, label="ship's track")
    priors, names = [], ["array centre", *tids]
    for j, tid in enumerate(tids):
        t = s["transponders"][tid]
        pr = np.array([t["prior"][c] for c in ("east", "north", "up")])
        priors.append(pr)
        ax.plot(pr[0], pr[1], "^", color=SURVEY_IN_COLORS["spurious"], mfc="none", ms=8,
                label="prior position" if j == 0 else None)
        ax.plot(t["enu"]["east"]["mean"], t["enu"]["north"]["mean"], "*", color="k", ms=10,
                label="solution" if j == 0 else None)
        ax.annotate(tid, (t["enu"]["east"]["mean"], t["enu"]["north"]["mean"]),
                    textcoords="offset points", xytext=(6, 6))
    c = s["array_centre"]
    ax.plot(c["enu"]["east"]["mean"], c["enu"]["north"]["mean"], "P", color="k", ms=9,
            label="array centre")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.legend(loc="best", fontsize="small")
    entries = [(c["enu"], np.mean(priors, axis=0), c["covariance"]["matrix"])] + [
        (s["transponders"][t]["enu"], priors[k], s["transponders"][t]["covariance"]["matrix"])
        for k, t in enumerate(tids)]
    trues = [None] * len(names)
    if truth is not None:
        trues = [truth["array_centre"]] + [truth["transponders"].get(str(t)) for t in tids]
    for j, (name, (enu, pr, cov)) in enumerate(zip(names, entries, strict=True)):
        r, col = divmod(j, ncol)
        m = np.array([enu[k]["mean"] for k in ("east", "north", "up")])
        d = 100.0 * (m - pr)
        tr = None if trues[j] is None else 100.0 * (
            np.array([trues[j][k] for k in ("east", "north", "up")]) - pr)
        _offset_panel(fig.add_subplot(gs[r, 2 + col]), name, d[:2],
                      1e4 * np.asarray(cov, float)[:2, :2], d[2], 100.0 * enu["up"]["sd"], ci,
                      true_cm=tr)
    fig.suptitle(f"Array: positions against their priors (cm), {100 * ci:g} % ellipses")
    return fig
