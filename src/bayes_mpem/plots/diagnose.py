"""Figures of :func:`bayes_mpem.diagnose`."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FuncFormatter

from .._validate import check_choice
from ..io.results import write_file, writing
from .style import CLASS_NAMES, class_color

_COV_LABELS = {"time": "time (s)", "range": "direct-path length (m)",
               "elevation": "elevation angle (deg)", "vehicle_depth": "vehicle depth (m)",
               "bearing": "bearing from beacon (deg)"}


def running_mean(p, window: int):
    """Centred running mean over ``window`` values, over fewer at the ends (no dip there)."""
    p = np.asarray(p, float)
    c = np.concatenate([[0.0], np.cumsum(p)])
    i = np.arange(p.size)
    half = int(window) // 2
    lo, hi = np.maximum(i - half, 0), np.minimum(i + half + 1, p.size)
    return (c[hi] - c[lo]) / (hi - lo)


def _binned(x, r, n_bins=12):
    edges = np.unique(np.quantile(x, np.linspace(0, 1, n_bins + 1)))
    if edges.size < 2:
        return np.array([]), np.array([])
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    cnt = np.bincount(idx, minlength=edges.size - 1)
    ok = cnt > 0
    mid = 0.5 * (edges[1:] + edges[:-1])
    return mid[ok], (np.bincount(idx, weights=r, minlength=edges.size - 1)[ok] / cnt[ok])


def plot_residuals(diagnosis, *, model="baseline", fig=None, max_points=4000):
    """Direct-path and multipath residuals against time, range, elevation, depth, bearing."""
    check_choice("model", model, ("baseline", "final"), words=True)
    fit = diagnosis.baseline if model == "baseline" else diagnosis.final
    d = diagnosis.data
    tab, info = diagnosis.replies(), diagnosis.figure_info()[model]
    cov = {name: tab[name].to_numpy(float) for name in _COV_LABELS}
    res = {cls: tab[f"{model}_residual_{cls}"].to_numpy(float) for cls in ("dp", "mp")}
    names = list(_COV_LABELS)
    if fig is None:
        fig = plt.figure(figsize=(15, 5.6), layout="constrained")
    axes = fig.subplots(2, len(names), squeeze=False, sharey="row")
    gen = np.random.default_rng(0)
    for row, cls in enumerate(("dp", "mp")):
        col_c = 0 if cls == "dp" else 1
        for j, bid in enumerate(d.ids):
            sel = np.flatnonzero((d.bi == j) & (fit.resp[:, col_c] > 0.5))
            if sel.size == 0:
                continue
            show = sel if sel.size <= max_points // d.nb else gen.choice(
                sel, max_points // d.nb, replace=False)
            r = res[cls]
            for ax, name in zip(axes[row], names, strict=True):
                ax.plot(cov[name][show], r[show], ".", ms=1.5, alpha=0.35, color=f"C{j}")
                xm, ym = _binned(cov[name][sel], r[sel])
                ax.plot(xm, ym, "-", color=f"C{j}", lw=1.8, label=f"beacon {bid}")
        for ax, name in zip(axes[row], names, strict=True):
            ax.axhline(0.0, color="k", lw=0.6)
            if row == 1:
                ax.set_xlabel(_COV_LABELS[name])
        sig = info[f"sigma_{cls}"]
        axes[row, 0].set_ylim(-6 * sig, 6 * sig)
        axes[row, 0].set_ylabel(f"{'direct-path' if cls == 'dp' else 'multipath'} residual (m)")
    axes[0, -1].legend(fontsize="small", markerscale=4)
    eff = ", ".join(fit.effects) if fit.effects else "no effect"
    fig.suptitle(f"Residuals of the {model} model ({eff}; {fit.path} multipath)")
    return fig


def plot_classes_vs_time(diagnosis, *, model="final", fig=None, window=101):
    """Plot the running mean of each class probability against time, one panel per beacon.

    Parameters
    ----------
    window : int, default 101
        Replies in the running mean.
    """
    fit = diagnosis.baseline if model == "baseline" else diagnosis.final
    d = diagnosis.data
    if fig is None:
        fig = plt.figure(figsize=(10, 1.9 * d.nb + 0.6), layout="constrained")
    axes = fig.subplots(d.nb, 1, squeeze=False, sharex=True)[:, 0]
    for j, (ax, bid) in enumerate(zip(axes, d.ids, strict=True)):
        sel = np.flatnonzero(d.bi == j)
        sel = sel[np.argsort(d.time[sel], kind="stable")]
        for c, name in enumerate(("dp", "mp", "mp2", "ol")):
            p = fit.resp[sel, c]
            if name == "mp2" and not p.any():
                continue
            ax.plot(d.time[sel], running_mean(p, window), color=class_color(name),
                    label=CLASS_NAMES[name])
        ax.set_ylim(0, 1)
        ax.set_ylabel(f"beacon {bid}")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=4,
               fontsize="small")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(f"Class probabilities against time ({model} model, running mean of {window})")
    return fig


def plot_candidates(diagnosis, *, fig=None):
    """Held-out gain of every extension tried, round by round, with the selection rule."""
    cands = [c for c in diagnosis.candidates if c["delta_elpd"] is not None]
    # forward rounds in order, then the backward step (its gain: the cost of removing)
    rounds = list(dict.fromkeys(c["round"] for c in cands))
    order = list(dict.fromkeys(c["name"] for c in cands))  # every term tried, as first tried
    if fig is None:
        fig = plt.figure(figsize=(4 + 3 * max(len(rounds), 1), 1.6 + 0.25 * len(order)),
                         layout="constrained")
    axes = fig.subplots(1, max(len(rounds), 1), squeeze=False, sharey=True)[0]
    for ax, rnd in zip(axes, rounds, strict=False):
        cs = [c for c in cands if c["round"] == rnd]
        y = np.array([order.index(c["name"]) for c in cs])
        vals = np.array([c["delta_elpd"] for c in cs])
        err = np.array([2 * c["se"] for c in cs])
        colors = ["tab:green" if c["kept"] else "0.6" for c in cs]
        ax.barh(y, vals, xerr=err, color=colors)
        ax.set_yticks(np.arange(len(order)), order)
        ax.set_ylim(len(order) - 0.5, -0.5)
        ax.axvline(diagnosis.settings["min_gain"], color="k", ls=":", lw=0.8)
        ax.axvline(0.0, color="k", lw=0.6)
        ax.set_xscale("symlog", linthresh=10.0)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))  # 1000, not 10^3
        ax.set_xlabel("held-out log predictive density gain (nats)")
        ax.set_title(f"round {rnd}" if isinstance(rnd, int) else "backward step (cost of "
                     "removing)", fontsize="medium")
    fig.suptitle("Extensions tried (green: kept; bars ± 2 SE; dotted: minimum gain)")
    return fig


def write_figures(diagnosis, out_dir) -> dict:
    """Write the diagnostic figures as PNG files.

    Returns
    -------
    dict
        Paths keyed by figure name.
    """
    paths = {}
    with writing(out_dir) as out:
        for key, make in (("residuals_baseline", lambda: plot_residuals(diagnosis)),
                          ("residuals_final", lambda: plot_residuals(diagnosis, model="final")),
                          ("classes_vs_time", lambda: plot_classes_vs_time(diagnosis)),
                          ("candidates", lambda: plot_candidates(diagnosis))):
            fig = make()
            try:
                paths[key] = write_file(out / f"{key}.png",
                                        lambda tmp, f=fig: f.savefig(tmp, dpi=100))
            finally:
                plt.close(fig)
    return paths
