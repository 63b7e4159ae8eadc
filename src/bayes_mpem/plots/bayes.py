"""Figures of the Bayesian variant."""

from __future__ import annotations

import textwrap

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import MaxNLocator

from .style import PARAM_LABELS, class_colors, class_key

#: the axis labels of the parameters (:data:`~bayes_mpem.plots.style.PARAM_LABELS`)
LABELS = PARAM_LABELS


def _draws(result, names=None):
    post = result.idata.posterior
    names = [n for n in (names or LABELS) if n in post.data_vars]
    return names, {n: post[n].values for n in names}  # (chain, draw)


def plot_trace(result, *, params=None, fig=None):
    """Walker traces (kept, thinned draws) and marginal histograms.

    Parameters
    ----------
    params : list of str, optional
        Subset of ``d0``, ``sigma_mp``, ``sigma_dp``, ``w_dp``, ``w_mp``, ``w_ol``.
    """
    names, d = _draws(result, params)
    if fig is None:
        fig = plt.figure(figsize=(10, 1.8 * len(names)), layout="constrained")
    axes = fig.subplots(len(names), 2, squeeze=False, width_ratios=[3, 1])
    for (ax_t, ax_h), n in zip(axes, names, strict=True):
        ax_t.plot(d[n].T, lw=0.4, alpha=0.5)
        ax_t.set_ylabel(LABELS[n])
        ax_h.sharey(ax_t)  # the histogram beside the trace, on the same scale
        ax_h.hist(d[n].ravel(), bins=40, orientation="horizontal", color="0.4")
        ax_h.tick_params(labelleft=False)
        ax_h.set_xticks([])  # counts carry no information here
        s = result.summary.get(n) or result.summary["weights"][n[2:]]
        for v in s["interval"]:
            ax_h.axhline(v, color="k", ls="--", lw=0.8,
                         label=f"{100 * result.ci:g} % HDI" if v == s["interval"][0] else None)
        ax_t.set_title(f"bulk ESS = {result.ess.get(n, float('nan')):,.0f}, R-hat = "
                       f"{(result.rhat or {}).get(n, float('nan')):.3f}", fontsize="small",
                       loc="left")
    axes[0, 1].legend(fontsize="x-small", loc="upper right")
    axes[-1, 0].set_xlabel(f"kept draw (thinned by {result.diagnostics.get('thin', 1)} steps)")
    diag = result.diagnostics
    moves = ("independence proposal" if diag.get("sampler") == "independence"
             else "differential evolution")
    fig.suptitle(f"beacon {result.beacon}: {result.priors} priors, "
                 f"{diag.get('n_chains', diag.get('n_walkers'))} emcee walkers ({moves})")
    return fig


def plot_pair(result, *, params=None, fig=None, max_points=3000):
    """Corner plot of the posterior: histograms on the diagonal, draws below.

    Parameters
    ----------
    params : list of str, optional
        Default: every sampled parameter (d0, sigma_MP, sigma_DP, weights).
    max_points : int, default 3000
        Draws shown in the scatter panels.
    """
    names, d = _draws(result, params)
    k = len(names)
    if fig is None:
        fig = plt.figure(figsize=(2.0 * k, 2.0 * k), layout="constrained")
    axes = fig.subplots(k, k, squeeze=False)
    flat = {n: d[n].ravel() for n in names}
    step = max(1, flat[names[0]].size // max_points)
    for i, ni in enumerate(names):
        for j, nj in enumerate(names):
            ax = axes[i, j]
            if j > i:
                ax.set_axis_off()
                continue
            if i == j:
                ax.hist(flat[ni], bins=40, color="0.4")
                ax.set_yticks([])
            else:
                ax.plot(flat[nj][::step], flat[ni][::step], ".", ms=1, alpha=0.3, color="0.2")
                ax.set_yticks(_inner_ticks(ax.get_ylim()))
            ax.set_xticks(_inner_ticks(ax.get_xlim()))
            if i == k - 1:
                ax.set_xlabel(LABELS[nj])
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(LABELS[ni])
            elif j > 0:
                ax.set_yticklabels([])
    fig.suptitle(f"beacon {result.beacon}: {result.priors} priors")
    return fig


def _inner_ticks(lim, n=3, edge=0.15):
    """Round ticks inside the middle of ``lim``: labels of neighbouring panels never meet."""
    lo, hi = lim
    span = hi - lo
    ticks = MaxNLocator(n).tick_values(lo, hi)
    inner = [t for t in ticks if lo + edge * span <= t <= hi - edge * span]
    return inner or [ticks[len(ticks) // 2]]


def _interval_rows(survey_posterior, key, truth):
    rows = []
    for bid, r in survey_posterior.results.items():
        s = r.summary[key]
        depth = float(survey_posterior.survey.beacons.loc[bid, "depth"])
        if key == "d0":  # show the plane depth: 0 for the sea surface
            mean, (lo, hi) = depth - s["mean"], (depth - s["interval"][1], depth - s["interval"][0])
            t = None if truth is None else depth - truth[bid]["d0"]
        else:
            mean, (lo, hi) = s["mean"], s["interval"]
            t = None if truth is None else truth[bid][key]
        rows.append((bid, mean, lo, hi, t))
    return rows


def plot_intervals(survey_posterior, *, truth=None, fig=None):
    """Posterior mean and interval of the plane depth and sigma_MP for every beacon.

    Parameters
    ----------
    truth : dict, optional
        ``Simulation.truth``: marks the true values.
    """
    if fig is None:
        fig = plt.figure(figsize=(9, 1 + 0.5 * len(survey_posterior.results)),
                         layout="constrained")
    axes = fig.subplots(1, 2, squeeze=False)[0]
    pct = f"{100 * survey_posterior.ci:g} %"
    for ax, key, label in ((axes[0], "d0", "plane depth = beacon depth - d0 (m)"),
                           (axes[1], "sigma_mp", "sigma_MP (m)")):
        rows = _interval_rows(survey_posterior, key, truth)
        y = np.arange(len(rows))
        for yi, (_, mean, lo, hi, t) in zip(y, rows, strict=True):
            ax.plot([lo, hi], [yi, yi], color="tab:blue", lw=2)
            ax.plot(mean, yi, "o", color="tab:blue")
            if t is not None:
                ax.plot(t, yi, "x", color="tab:red", ms=8, label="truth" if yi == 0 else None)
        ax.set_yticks(y, [f"beacon {r[0]}" for r in rows])
        ax.set_xlabel(label)
        ax.invert_yaxis()
    axes[0].set_title(f"posterior mean and {pct} HDI ({survey_posterior.priors} priors)",
                      loc="left", fontsize="medium")
    if truth is not None:
        axes[1].legend(loc="best", fontsize="small")
    return fig


def plot_prior_comparison(survey_comparison, *, fig=None):
    """Equal against learned priors: intervals side by side and the ELPD difference."""
    res = survey_comparison.results
    if fig is None:
        fig = plt.figure(figsize=(12, 1.2 + 0.6 * len(res)), layout="constrained")
    axes = fig.subplots(1, 3, squeeze=False)[0]
    y = np.arange(len(res))
    colors = {"equal": "tab:orange", "learned": "tab:blue"}
    panels = ((axes[0], "d0", "d0 - EM d0 (m)"), (axes[1], "sigma_mp", "sigma_MP (m)"))
    for ax, key, label in panels:
        for yi, r in zip(y, res.values(), strict=True):
            ref = r.learned.em.d0 if key == "d0" else 0.0
            for off, name in ((-0.15, "equal"), (0.15, "learned")):
                s = r.shifts[key][name]
                lo, hi = (v - ref for v in s["interval"])
                ax.plot([lo, hi], [yi + off] * 2, color=colors[name], lw=2,
                        label=name if yi == 0 else None)
                ax.plot(s["mean"] - ref, yi + off, "o", color=colors[name])
        ax.set_yticks(y, [f"beacon {b}" for b in res])
        ax.set_xlabel(label)
        ax.invert_yaxis()
    axes[0].legend(loc="best", fontsize="small", title="priors")
    ax = axes[2]
    for yi, r in zip(y, res.values(), strict=True):
        ax.errorbar(r.elpd_diff, yi, xerr=2 * r.elpd_diff_se, fmt="o", color="k", capsize=3)
    ax.axvline(0, color="0.5", lw=0.8)
    ax.set_yticks(y, [f"beacon {b}" for b in res])
    ax.invert_yaxis()
    ax.set_xlabel("ELPD learned - equal (+- 2 SE)")
    fig.suptitle("Equal (paper) against learned mixing priors")
    return fig


def plot_class_uncertainty(survey_posterior, beacon, *, fig=None):
    """Range against time coloured by posterior class probability (top), and its sd (bottom)."""
    r = survey_posterior.results[beacon]
    data = survey_posterior.survey.for_beacon(beacon)
    if fig is None:
        fig = plt.figure(figsize=(10, 6), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    col = class_colors(r.class_probs)
    ax1.scatter(data.time, data.range, c=col, s=4, linewidths=0)
    ax1.set_ylabel("one-way range (m)")
    ax1.set_title(f"beacon {beacon}: posterior class probabilities ({r.priors} priors)")
    class_key(ax1)
    j = np.argmax(r.class_probs, axis=1)
    p = r.class_probs[np.arange(j.size), j]
    sd = r.class_probs_sd[np.arange(j.size), j]
    ax2.errorbar(data.time, p, yerr=sd, fmt="none", ecolor="0.6", elinewidth=0.6)
    ax2.scatter(data.time, p, c=col, s=4, linewidths=0)
    ax2.set_ylim(0, 1.05)
    ax2.set_ylabel("P(most probable class)")
    ax2.set_xlabel("time (s)")
    return fig


def plot_sbc_ranks(results, *, n_bins=10, fig=None):
    """Rank histograms of simulation-based calibration (grey: the 99 % band of uniform ranks).

    Parameters
    ----------
    results : SBCResult or dict of str to SBCResult
        :func:`bayes_mpem.lbl.bayes.sbc.run_sbc` results, labelled (e.g. by move set).
    n_bins : int, default 10
        A divisor of ``n_draws + 1``.
    """
    from scipy import stats

    from ..mcmc.sbc import rank_histogram

    if not isinstance(results, dict):
        results = {"": results}
    names = next(iter(results.values())).names
    if fig is None:
        fig = plt.figure(figsize=(1.9 * len(names) + 1, 1.7 * len(results) + 0.6),
                         layout="constrained")
    axes = fig.subplots(len(results), len(names), squeeze=False, sharey="row")
    for r, (label, res) in enumerate(results.items()):
        n = len(res.ranks)
        lo, hi = stats.binom.interval(0.99, n, 1.0 / n_bins)
        for i, k in enumerate(names):
            ax = axes[r, i]
            counts = rank_histogram(res.ranks[:, i], res.n_draws, n_bins)
            ax.axhspan(lo, hi, color="0.85")
            ax.axhline(n / n_bins, color="0.5", lw=0.8)
            ax.bar(np.arange(n_bins), counts, width=1.0, color="tab:blue", edgecolor="white")
            ax.set_xticks([])
            if r == 0:
                ax.set_title(LABELS.get(k, k), fontsize="small")
            if r == len(results) - 1:
                ax.set_xlabel("rank, low to high", fontsize="x-small")
            if i == 0:
                ax.set_ylabel(textwrap.fill(f"{label} (n = {n})" if label else f"n = {n}", 22),
                              fontsize="x-small")
    fig.suptitle("SBC rank histograms (band: 99 % range under uniform ranks)")
    return fig
