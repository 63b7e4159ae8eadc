"""Where does the paper's EM find the reflecting plane, and why does it fail elsewhere?

Runs :func:`bayes_mpem.fit_paper_em` (chi-square tail "likelihoods", constant
outlier threshold ``Pol``, eq. 8 plane-height average blended by ``alpha``,
start at sigma_MP^2 = 1e7 m^2, d0 = 4000 m) over grids of simulated surveys
and writes ``docs/paper-em-regimes.md``:

1. mixing weights (MP and OL fractions) at Pol = 0.05, alpha = 0.5 (and
   Pol = 0.2), with :func:`bayes_mpem.fit_mixture_em` on the same data;
2. Pol x alpha on the ABE58-like preset (all four beacons);
3. the paper's qualitative Pol claims on beacon 4, where the method works;
4. geometry: vehicle altitude and horizontal beacon distance;
5. the starting values (sigma_MP(0), d0(0));
6. random surveys (the ``"random"`` preset);
plus two mechanism tables (an eq. 8 trace split by true class, and the
fixed point of sigma_MP for an idealised pure-Gaussian multipath cluster).

A fit "finds the plane" when |d0 - true d0| < 5 m. Every other fit gets one
failure mode (first matching rule):

* ``broad``    broad fixed point: sigma_MP > 100 m;
* ``captured`` captured by the direct path: d0 within 200 m of the median of
  z_beacon - z_vehicle (where the direct-path ranges' per-range d0(k) sit);
* ``collapse`` sigma_MP < 0.5 m with d0 elsewhere;
* ``near``     near miss: |d0 - true d0| < 50 m;
* ``start``    stuck at the start: d0 within 100 m of d0(0);
* ``other``    anything else.

The hand-written explanation in the doc sits between the
``<!-- BEGIN EXPLANATION -->`` / ``<!-- END EXPLANATION -->`` markers and is
kept when the script rewrites the file. ``--quick`` (fewer seeds) prints the
markdown instead of overwriting the doc, unless ``--out`` is given.

Usage::

    /work/venv/bin/python benchmarks/paper_em_regimes.py            # ~2 min, 1 core
    /work/venv/bin/python benchmarks/paper_em_regimes.py --quick    # smoke run
"""

from __future__ import annotations

import argparse
import datetime as _dt
import functools
import hashlib
import shlex
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import special

import bayes_mpem as bm
from bayes_mpem.lbl.em.em_paper import paper_e_step, paper_m_step
from bayes_mpem.lbl.model import geometry
from bayes_mpem.lbl.model.beacon_geometry import BeaconGeometry

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "docs" / "paper-em-regimes.md"
BEGIN, END = "<!-- BEGIN EXPLANATION -->", "<!-- END EXPLANATION -->"

SUCCESS_M = 5.0  # |d0 - truth| below this: the plane is found
BROAD_M = 100.0
COLLAPSE_M = 0.5
CAPTURE_M = 200.0
NEAR_M = 50.0
START_M = 100.0
MODES = ("found", "broad", "captured", "collapse", "near", "start", "other")
SIGMA_DP = 3.97  # the paper's sigma_DP, also the preset's (taken as known, as in the paper)
POLS = (0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5)
ALPHAS = (0.1, 0.5, 1.0)
BEACONS = ("1", "2", "3", "4")


# --------------------------------------------------------------------------
# one fit


def classify(d0, sigma_mp, truth_d0, dz_median, d0_init=4000.0):
    """Name the outcome of one fit (see the module docstring for the rules)."""
    err = abs(d0 - truth_d0)
    if not np.isfinite(d0) or not np.isfinite(sigma_mp):
        return "other"
    if err < SUCCESS_M:
        return "found"
    if sigma_mp > BROAD_M:
        return "broad"
    if abs(d0 - dz_median) < CAPTURE_M:
        return "captured"
    if sigma_mp < COLLAPSE_M:
        return "collapse"
    if err < NEAR_M:
        return "near"
    if abs(d0 - d0_init) < START_M:
        return "start"
    return "other"


def run_fit(data, truth, method="paper", *, pol=0.05, alpha=0.5, sigma_dp=SIGMA_DP,
            sigma_mp2_init=1e7, d0_init=4000.0, labels=None):
    """Fit one beacon and return a flat record (warnings recorded, not raised).

    Parameters
    ----------
    data : bayes_mpem.BeaconData
    truth : dict
        ``Simulation.truth[beacon]``.
    method : {"paper", "mixture"}
    pol, alpha, sigma_dp, sigma_mp2_init, d0_init
        Options of :func:`bayes_mpem.fit_paper_em` (ignored for the mixture EM,
        which estimates sigma_DP itself and is seeded with ``rng=0``).
    labels : numpy.ndarray, optional
        True class of every range of ``data``; gives ``dp_real_d0k``, the
        fraction of direct-path ranges that have a real per-range d0(k) and so
        enter eq. 8.

    Returns
    -------
    dict
    """
    geom = BeaconGeometry.from_data(data)
    dz_med = float(np.median(geom.dz))
    dp_real = float("nan")
    if labels is not None:
        d0k = geometry.invert_plane_height(geom.z, geom.h, geom.dz, direct=geom.direct)
        is_dp = np.asarray(labels) == "dp"
        dp_real = float(np.isfinite(d0k[is_dp]).mean()) if is_dp.any() else float("nan")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if method == "paper":
            res = bm.fit_paper_em(data, pol=pol, alpha=alpha, sigma_dp=sigma_dp,
                                  sigma_mp2_init=sigma_mp2_init, d0_init=d0_init)
        else:
            res = bm.fit_mixture_em(data, rng=0)
    n_warn = sum(issubclass(w.category, bm.ConvergenceWarning) for w in caught)
    t_d0, t_smp = float(truth["d0"]), float(truth["sigma_mp"])
    sep = float(np.median(geom.multipath(t_d0, "triangle") - geom.direct))
    gap = (float(np.median(np.abs(geom.multipath(res.d0, "triangle") - geom.direct)))
           if np.isfinite(res.d0) else float("nan"))
    return {
        "method": method, "beacon": data.beacon, "n": data.n,
        "d0": res.d0, "truth_d0": t_d0, "err": res.d0 - t_d0,
        "sigma_mp": res.sigma_mp, "truth_sigma_mp": t_smp, "sigma_ratio": res.sigma_mp / t_smp,
        "n_iter": res.n_iter, "converged": bool(res.converged), "conv_warning": n_warn,
        "p_dp": res.weights["dp"], "p_mp": res.weights["mp"], "p_ol": res.weights["ol"],
        "dz_median": dz_med, "dp_real_d0k": dp_real, "mp_dp_sep": sep, "mp_dp_gap_fit": gap,
        "mode": classify(res.d0, res.sigma_mp, t_d0, dz_med,
                         d0_init if method == "paper" else np.nan),
    }


def fit_survey(sim, cell, seed, beacons=None, methods=("paper",), **paper_kw):
    """Fit every (or the listed) beacon of a simulation; one record per fit."""
    out = []
    ids = beacons if beacons is not None else sim.survey.beacon_ids
    labels = sim.survey.table["true_class"].to_numpy()
    for b in ids:
        data = sim.survey.for_beacon(b)
        for m in methods:
            kw = paper_kw if m == "paper" else {}
            rec = run_fit(data, sim.truth[b], m, labels=labels[data.rows], **kw)
            out.append({**cell, "seed": seed, **rec})
    return out


# --------------------------------------------------------------------------
# grids


def grid_weights(seeds, pols=(0.05, 0.2)):
    """Grid 1: MP fraction x OL fraction (DP the rest), the same for all 4 beacons."""
    recs = []
    for w_mp in (0.1, 0.2, 0.3, 0.4, 0.5):
        for w_ol in (0.05, 0.15, 0.3):
            w = (round(1.0 - w_mp - w_ol, 10), w_mp, w_ol)
            for seed in seeds:
                sim = bm.simulate_survey("abe58", rng=seed, weights={b: w for b in BEACONS})
                cell = {"w_mp": w_mp, "w_ol": w_ol, "w_dp": w[0]}
                recs += fit_survey(sim, {**cell, "pol": np.nan}, seed, methods=("mixture",))
                for pol in pols:
                    recs += fit_survey(sim, {**cell, "pol": pol}, seed, pol=pol, alpha=0.5)
    return pd.DataFrame(recs)


def grid_pol_alpha(seeds):
    """Grid 2: Pol x alpha on the ABE58-like preset (default weights)."""
    recs = []
    for seed in seeds:
        sim = bm.simulate_survey("abe58", rng=seed)
        for pol in POLS:
            for alpha in ALPHAS:
                recs += fit_survey(sim, {"pol": pol, "alpha": alpha}, seed, pol=pol, alpha=alpha)
    return pd.DataFrame(recs)


def grid_altitude(seeds, altitudes=(30.0, 300.0, 1000.0)):
    """Grid 3a: vehicle altitude above the seafloor, ABE58-like beacons."""
    recs = []
    for alt in altitudes:
        for seed in seeds:
            sim = bm.simulate_survey("abe58", rng=seed, altitude=alt)
            recs += fit_survey(sim, {"altitude": alt}, seed, methods=("paper", "mixture"),
                               pol=0.05, alpha=0.5)
    return pd.DataFrame(recs)


def grid_distance(seeds, distances=(0.0, 1000.0, 2000.0, 3500.0),
                  altitudes=(30.0, 300.0, 1000.0),
                  weight_sets=((0.50, 0.35, 0.15), (0.40, 0.45, 0.15))):
    """Grid 3b: one beacon at horizontal distance D from the survey-box centre x altitude.

    The beacon sits at the mean seafloor depth (2430 m), east of the centre of
    the 1500 m x 1200 m box; weights (DP, MP, OL) from ``weight_sets``,
    sigma_MP = 7 m.
    """
    box = bm.simulate.ABE58["box"]
    cx, cy = 0.5 * (box[0] + box[1]), 0.5 * (box[2] + box[3])
    depth = float(bm.simulate.ABE58["seafloor"])
    recs = []
    for weights in weight_sets:
        for dist in distances:
            beacons = {"1": {"x": cx + dist, "y": cy, "depth": depth}}
            for alt in altitudes:
                for seed in seeds:
                    sim = bm.simulate_survey("abe58", rng=seed, altitude=alt, beacons=beacons,
                                             sigma_mp={"1": 7.0}, weights={"1": weights})
                    cell = {"w_mp": weights[1], "distance": dist, "altitude": alt}
                    recs += fit_survey(sim, cell, seed, methods=("paper", "mixture"),
                                       pol=0.05, alpha=0.5)
    return pd.DataFrame(recs)


def grid_init(seeds, sigma0s=(10.0, 100.0, 1000.0, 1e7 ** 0.5)):
    """Grid 5: starting values sigma_MP(0) x d0(0) in {4000 m, the true plane}."""
    recs = []
    for seed in seeds:
        sim = bm.simulate_survey("abe58", rng=seed)
        for s0 in sigma0s:
            for d0_start in ("4000", "truth"):
                for b in BEACONS:
                    d0i = 4000.0 if d0_start == "4000" else sim.truth[b]["d0"]
                    rec = run_fit(sim.survey.for_beacon(b), sim.truth[b], "paper", pol=0.05,
                                  alpha=0.5, sigma_mp2_init=s0 * s0, d0_init=d0i)
                    recs.append({"sigma0": s0, "d0_start": d0_start, "seed": seed, **rec})
    return pd.DataFrame(recs)


def grid_frozen(seeds, beacon="4"):
    """Mechanism C: eq. 9 with d0 held at the true plane vs the free EM (beacon 4).

    d0 is frozen by ``alpha = 1e-9`` with ``d0_init`` = the true plane and
    sigma_MP(0) = 100 m; the free run is the paper's (alpha = 0.5, 1e7, 4000 m).
    """
    recs = []
    for seed in seeds:
        sim = bm.simulate_survey("abe58", rng=seed)
        data, truth = sim.survey.for_beacon(beacon), sim.truth[beacon]
        for pol in POLS:
            free = run_fit(data, truth, pol=pol, alpha=0.5)
            frozen = run_fit(data, truth, pol=pol, alpha=1e-9, d0_init=truth["d0"],
                             sigma_mp2_init=1e4)
            recs.append({"seed": seed, "pol": pol, "free_sigma": free["sigma_mp"],
                         "free_mode": free["mode"], "free_d0": free["d0"],
                         "frozen_sigma": frozen["sigma_mp"], "truth_sigma_mp": truth["sigma_mp"]})
    return pd.DataFrame(recs)


def grid_random(seeds):
    """Grid 6: the ``"random"`` preset; the paper's EM gets the true sigma_DP."""
    recs = []
    for seed in seeds:
        sim = bm.simulate_survey("random", rng=seed)
        s_dp = float(sim.config["sigma_dp"])
        alt = float(sim.config["altitude"])
        labels = sim.survey.table["true_class"].to_numpy()
        for b in sim.survey.beacon_ids:
            data = sim.survey.for_beacon(b)
            for m in ("paper", "mixture"):
                rec = run_fit(data, sim.truth[b], m, pol=0.05, alpha=0.5, sigma_dp=s_dp,
                              labels=labels[data.rows])
                recs.append({"seed": seed, "altitude": alt, **rec})
    return pd.DataFrame(recs)


# --------------------------------------------------------------------------
# mechanism


def trace_paper_em(data, labels, *, pol=0.05, alpha=0.5, sigma_dp=SIGMA_DP, tol=1e-3,
                   max_iter=2000):
    """Re-run the paper's EM step by step, splitting eq. 8 by the true class.

    Uses the library's own :func:`bayes_mpem.lbl.em.em_paper.paper_e_step` and
    :func:`~bayes_mpem.lbl.em.em_paper.paper_m_step`, with the stopping rule of
    :func:`bayes_mpem.fit_paper_em`.

    Returns
    -------
    pandas.DataFrame
        One row per iteration: ``d0``, ``sigma_mp`` (the values used by that
        E-step), mean gamma_MP of the true DP / MP / OL ranges, the share of
        the eq. 8 weight carried by true-DP ranges and the eq. 8 average.
    """
    geom = BeaconGeometry.from_data(data)
    d0k = geometry.invert_plane_height(geom.z, geom.h, geom.dz, "triangle", direct=geom.direct)
    ok = np.isfinite(d0k)
    d0, s = 4000.0, float(np.sqrt(1e7))
    rows = []
    for it in range(max_iter + 1):
        resp = paper_e_step(geom, d0, s, sigma_dp, pol)
        g = resp[:, 1]
        w = np.where(ok, g, 0.0)
        rows.append({
            "iter": it, "d0": d0, "sigma_mp": s,
            **{f"g_{c}": float(g[labels == c].mean()) for c in ("dp", "mp", "ol")},
            "dp_share": float(w[labels == "dp"].sum() / w.sum()),
            "eq8_avg": float(np.dot(w, np.where(ok, d0k, 0.0)) / w.sum()),
        })
        d0_new, s_new = paper_m_step(geom, g, d0, alpha)
        done = abs(d0_new - d0) < tol and abs(s_new - s) < tol
        d0, s = d0_new, s_new
        if done or not np.isfinite(s) or s <= 0:
            rows.append({"iter": it + 1, "d0": d0, "sigma_mp": s})
            break
    return pd.DataFrame(rows), {"dp_finite": float(ok[labels == "dp"].mean()),
                                "dp_d0k_median": float(np.nanmedian(d0k[labels == "dp"])),
                                "mp_d0k_median": float(np.nanmedian(d0k[labels == "mp"]))}


# residual / sigma_MP: dense near 0 so that large t (narrow phi(t u)) is resolved too
_U = np.concatenate([np.linspace(0.0, 0.5, 50001), np.linspace(0.5, 40.0, 39501)[1:]])
_DU = np.gradient(_U)  # trapezoid-like quadrature weights


@functools.lru_cache(maxsize=64)
def _gamma_pure_mp(pol):
    """gamma_MP of a multipath range vs its residual in units of sigma_MP (no DP nearby)."""
    p = special.erfc(_U / np.sqrt(2.0))
    rest = 1.0 - p
    p_ol = np.where(rest < pol, np.clip(rest, 0.0, None), pol)
    return p / (p + p_ol) * _DU


def sigma_map_ratio(t, pol):
    """T(t) / t for the eq. 9 map on an infinite pure N(0, 1) multipath cluster.

    With the current sigma_MP = t (in units of the true scatter), eq. 9 returns
    T(t) = sqrt(E[gamma r^2] / E[gamma]); the integrals are taken in u = r / t.
    """
    g = _gamma_pure_mp(pol)
    phi = np.exp(-0.5 * (t * _U) ** 2)
    return float(np.sqrt(np.dot(g * phi, _U * _U) / np.sum(g * phi)))


def sigma_fixed_point(pol, t0=100.0, tol=1e-9, max_iter=100000):
    """Iterate eq. 9 from sigma = t0 (x true sigma); 0.0 if it collapses."""
    t = t0
    for _ in range(max_iter):
        t_new = t * sigma_map_ratio(t, pol)
        if abs(t_new - t) < tol:
            return t_new
        if t_new < 1e-4:
            return 0.0
        t = t_new
    return t


def critical_pol(lo=0.2, hi=0.6, n_bisect=20):
    """Largest Pol for which eq. 9 keeps a non-zero fixed point (pure-MP idealisation).

    A non-zero fixed point exists iff T(t) / t >= 1 for some t in (0, 1].
    """
    ts = np.geomspace(1e-3, 1.0, 100)

    def has_fixed_point(pol):
        return max(sigma_map_ratio(t, pol) for t in ts) >= 1.0

    for _ in range(n_bisect):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if has_fixed_point(mid) else (lo, mid)
    return 0.5 * (lo + hi)


# --------------------------------------------------------------------------
# markdown


def md_table(headers, rows):
    """A GitHub markdown table."""
    out = ["| " + " | ".join(map(str, headers)) + " |",
           "|" + "|".join("---" for _ in headers) + "|"]
    out += ["| " + " | ".join(map(str, r)) + " |" for r in rows]
    return "\n".join(out)


def frac(df):
    """'k/N' plane found."""
    return f"{int((df['mode'] == 'found').sum())}/{len(df)}"


def mode_summary(df, skip_found=True):
    """Failure modes as 'broad 3, captured 2'."""
    c = Counter(df["mode"])
    parts = [f"{m} {c[m]}" for m in MODES if c[m] and not (skip_found and m == "found")]
    return ", ".join(parts) if parts else "-"


def fmt(x, nd=2):
    """Number or '-'."""
    return "-" if x is None or not np.isfinite(x) else f"{x:.{nd}f}"


def median_found(df, col):
    """Median of ``col`` over the fits that found the plane."""
    s = df.loc[df["mode"] == "found", col]
    return float(s.median()) if len(s) else float("nan")


def section_weights(df, n_seeds):
    out = ["## 1. Mixing weights", "",
           f"ABE58-like preset, the same weights (DP, MP, OL) for all four beacons, "
           f"{n_seeds} seeds x 4 beacons = {4 * n_seeds} fits per cell. Cell: plane found / fits "
           "(failure modes of the rest). The paper's EM runs with alpha = 0.5, "
           "sigma_DP = 3.97 m; the mixture EM (`fit_mixture_em`, default options, `rng=0`) "
           "on the same data.", ""]
    w_ols = sorted(df["w_ol"].unique())
    w_mps = sorted(df["w_mp"].unique())
    for label, sel in (("Paper's EM, Pol = 0.05", (df.method == "paper") & (df.pol == 0.05)),
                       ("Paper's EM, Pol = 0.2", (df.method == "paper") & (df.pol == 0.2)),
                       ("Mixture EM", df.method == "mixture")):
        sub = df[sel]
        rows = []
        for w_mp in w_mps:
            row = [f"{w_mp:.2f}"]
            for w_ol in w_ols:
                c = sub[(sub.w_mp == w_mp) & (sub.w_ol == w_ol)]
                row.append(f"{frac(c)} ({mode_summary(c)})" if label != "Mixture EM"
                           else frac(c))
            rows.append(row)
        out += [f"**{label}**", "",
                md_table(["w_MP \\ w_OL"] + [f"{w:.2f} (w_DP = 1 - w_MP - w_OL)" if i == 0
                                             else f"{w:.2f}" for i, w in enumerate(w_ols)],
                         rows), ""]
    p05 = df[(df.method == "paper") & (df.pol == 0.05)]
    rows = []
    for w_mp in w_mps:
        c = p05[p05.w_mp == w_mp]
        rows.append([f"{w_mp:.2f}"] + [frac(c[c.beacon == b]) for b in BEACONS])
    out += ["**Paper's EM, Pol = 0.05, by beacon** (all w_OL pooled)", "",
            md_table(["w_MP", *[f"beacon {b}" for b in BEACONS]], rows), ""]
    rows = []
    ratio = (df.w_mp / df.w_dp).round(2)
    for r in sorted(ratio.unique()):
        sel = ratio == r
        cells = df[sel].drop_duplicates(["w_mp", "w_ol"])
        label = ", ".join(f"{a:.2f}/{b:.2f}/{c:.2f}" for a, b, c in
                          zip(cells.w_dp, cells.w_mp, cells.w_ol, strict=True))
        rows.append([f"{r:.2f}", label,
                     frac(df[sel & (df.method == "paper") & (df.pol == 0.05)]),
                     frac(df[sel & (df.method == "paper") & (df.pol == 0.2)]),
                     frac(df[sel & (df.method == "mixture")])])
    out += ["**Sorted by w_MP / w_DP** (same fits)", "",
            md_table(["w_MP / w_DP", "weights DP/MP/OL", "paper Pol 0.05", "paper Pol 0.2",
                      "mixture"], rows), ""]
    return out


def section_pol_alpha(df, n_seeds):
    out = ["## 2. Pol x alpha", "",
           f"ABE58-like preset with its default weights (beacon 1: 0.70/0.20/0.10, 2: "
           f"0.60/0.25/0.15, 3: 0.55/0.30/0.15, 4: 0.50/0.35/0.15), {n_seeds} seeds x 4 "
           "beacons per cell. sigma_MP/truth and iterations are medians over the fits that "
           "found the plane.", ""]
    rows = []
    for pol in POLS:
        row = [f"{pol:g}"]
        for alpha in ALPHAS:
            c = df[(df.pol == pol) & (df.alpha == alpha)]
            row.append(f"{frac(c)}; {fmt(median_found(c, 'sigma_ratio'))}; "
                       f"{fmt(median_found(c, 'n_iter'), 0)}")
        rows.append(row)
    out += ["**Found / fits; median sigma_MP/true; median iterations**", "",
            md_table(["Pol \\ alpha", *[f"{a:g}" for a in ALPHAS]], rows), ""]
    rows = []
    for pol in POLS:
        c = df[(df.pol == pol) & (df.alpha == 0.5)]
        rows.append([f"{pol:g}", *[f"{frac(c[c.beacon == b])} "
                                   f"({fmt(median_found(c[c.beacon == b], 'sigma_mp'), 2)})"
                                   for b in BEACONS], mode_summary(c)])
    out += ["**alpha = 0.5, by beacon: found / fits (median sigma_MP of those, m), and the "
            "failure modes**", "",
            md_table(["Pol", *[f"beacon {b}" for b in BEACONS], "failure modes"], rows), ""]
    rows = []
    for pol in POLS:
        rows.append([f"{pol:g}", *[mode_summary(df[(df.pol == pol) & (df.alpha == a)])
                                   for a in ALPHAS]])
    out += ["**Failure modes by Pol and alpha** (all beacons)", "",
            md_table(["Pol \\ alpha", *[f"{a:g}" for a in ALPHAS]], rows), ""]
    hollow = df[(df["mode"] == "found") & (df.sigma_mp < COLLAPSE_M)]
    warned = df[df.conv_warning > 0]
    warn = (f"{len(warned)} of {len(df)}: {int((warned.sigma_mp <= 0).sum())} stopped because "
            f"sigma_MP reached exactly 0, {int((warned.n_iter >= 2000).sum())} hit max_iter "
            f"= 2000; all at alpha = {', '.join(f'{a:g}' for a in sorted(warned.alpha.unique()))}")
    by_pol = ", ".join(f"{k:g}: {v}" for k, v in sorted(Counter(hollow.pol).items()))
    out += [f"Fits that found d0 but with a collapsed sigma_MP < {COLLAPSE_M} m: "
            f"{len(hollow)} of {int((df['mode'] == 'found').sum())} "
            f"(by Pol: {by_pol}). "
            f"Fits with a ConvergenceWarning: {warn}.", ""]
    return out


def section_claims(df, n_seeds, beacon="4"):
    sub = df[(df.beacon == beacon) & (df.alpha == 0.5)]
    t = sub.iloc[0]
    out = ["## 3. The paper's Pol claims where the method works (beacon 4)", "",
           f"Beacon 4 (true d0 = {t.truth_d0:.0f} m, sigma_MP = {t.truth_sigma_mp:g} m, "
           f"weights 0.50/0.35/0.15), alpha = 0.5, {n_seeds} seeds. d0 and sigma_MP are "
           "medians [min-max] over the fits that found the plane, and so are the mean class "
           "probabilities (the paper's Fig. 12c). 'Ideal sigma' is the eq. 9 fixed "
           "point for a pure Gaussian multipath cluster (mechanism table B) times the true "
           "sigma_MP.", ""]
    rows = []
    for pol in POLS:
        c = sub[sub.pol == pol]
        f = c[c["mode"] == "found"]
        d0s = (f"{f.d0.median():.1f} [{f.d0.min():.1f}-{f.d0.max():.1f}]" if len(f) else "-")
        sms = (f"{f.sigma_mp.median():.2f} [{f.sigma_mp.min():.2f}-{f.sigma_mp.max():.2f}]"
               if len(f) else "-")
        ideal = sigma_fixed_point(pol) * t.truth_sigma_mp
        rows.append([f"{pol:g}", frac(c), d0s, sms, fmt(ideal),
                     *[fmt(f[k].median() if len(f) else np.nan, 3)
                       for k in ("p_dp", "p_mp", "p_ol")]])
    out += [md_table(["Pol", "found", "d0 (m)", "sigma_MP (m)", "ideal sigma (m)",
                      "mean P(DP)", "mean P(MP)", "mean P(OL)"], rows), ""]
    return out


def section_geometry(df_alt, df_dist, n_seeds):
    out = ["## 4. Geometry", "",
           "### 4a. Vehicle altitude (ABE58-like beacons, default weights)", "",
           f"Pol = 0.05, alpha = 0.5, {n_seeds} seeds per cell. Median dz = z_beacon - "
           "z_vehicle is where the direct-path ranges' per-range d0(k) sit; 'DP in eq. 8' is "
           "the median fraction of true direct-path ranges that have a real d0(k) (the others "
           "are left out of eq. 8).", ""]
    rows = []
    for alt in sorted(df_alt.altitude.unique()):
        p = df_alt[(df_alt.altitude == alt) & (df_alt.method == "paper")]
        m = df_alt[(df_alt.altitude == alt) & (df_alt.method == "mixture")]
        rows.append([f"{alt:g}", f"{p.dz_median.median():.0f}", fmt(p.dp_real_d0k.median()),
                     *[frac(p[p.beacon == b]) for b in BEACONS], frac(p), mode_summary(p),
                     frac(m)])
    out += [md_table(["altitude (m)", "median dz (m)", "DP in eq. 8",
                      *[f"b{b}" for b in BEACONS], "paper all", "paper failure modes",
                      "mixture all"], rows), "",
            "### 4b. Beacon distance x altitude (one beacon, sigma_MP = 7 m)", "",
            "D = horizontal distance of the beacon (2430 m deep) from the centre of the "
            f"1500 m x 1200 m survey box. Pol = 0.05, alpha = 0.5, {n_seeds} seeds per cell. "
            "Cell: paper found / fits (failure modes) / mixture found.", ""]
    alts = sorted(df_dist.altitude.unique())
    for w_mp in sorted(df_dist.w_mp.unique()):
        rows = []
        for dist in sorted(df_dist.distance.unique()):
            row = [f"{dist:g}"]
            for alt in alts:
                c = df_dist[(df_dist.w_mp == w_mp) & (df_dist.distance == dist)
                            & (df_dist.altitude == alt)]
                p, m = c[c.method == "paper"], c[c.method == "mixture"]
                row.append(f"{frac(p)} ({mode_summary(p)}) / {frac(m)}")
            rows.append(row)
        out += [f"**w_MP = {w_mp:.2f}, w_OL = 0.15**", "",
                md_table(["D (m) \\ altitude (m)", *[f"{a:g}" for a in alts]], rows), ""]
    rows = []
    for dist in sorted(df_dist.distance.unique()):
        c = df_dist[df_dist.distance == dist]
        rows.append([f"{dist:g}", *[f"{c[c.altitude == a].mp_dp_sep.median():.0f}"
                                    for a in alts]])
    out += ["**Median multipath - direct-path range separation at the true plane (m)**", "",
            md_table(["D (m) \\ altitude (m)", *[f"{a:g}" for a in alts]], rows), ""]
    rows = []
    for alt in sorted(df_alt.altitude.unique()):
        c = df_alt[(df_alt.altitude == alt) & (df_alt.method == "paper")]
        rows.append([f"{alt:g}", *[f"{c[c.beacon == b].mp_dp_sep.median():.0f}"
                                   for b in BEACONS]])
    out += ["Same separation for the ABE58-like beacons of 4a:", "",
            md_table(["altitude (m)", *[f"beacon {b}" for b in BEACONS]], rows), ""]
    return out


def section_init(df, n_seeds):
    out = ["## 5. Starting values", "",
           f"ABE58-like preset, Pol = 0.05, alpha = 0.5, {n_seeds} seeds x 4 beacons per cell. "
           "The paper starts at sigma_MP(0) = sqrt(1e7) = 3162 m, d0(0) = 4000 m.", ""]
    rows = []
    for s0 in sorted(df.sigma0.unique()):
        row = [f"{s0:.0f}"]
        for start in ("4000", "truth"):
            c = df[(df.sigma0 == s0) & (df.d0_start == start)]
            row.append(f"{frac(c)} ({mode_summary(c)})")
        rows.append(row)
    out += [md_table(["sigma_MP(0) (m)", "d0(0) = 4000 m", "d0(0) = true plane"], rows), ""]
    return out


def section_random(df, n_seeds):
    p, m = df[df.method == "paper"], df[df.method == "mixture"]
    out = ["## 6. Random surveys", "",
           f"`simulate_survey(\"random\", rng=seed)` for {n_seeds} seeds ({len(p)} beacons): "
           "water 800-4500 m deep, vehicle 20 m above the floor up to mid-water, weights "
           "MP 0.12-0.45, OL 0.03-0.2. The paper's EM gets the true sigma_DP, Pol = 0.05, "
           "alpha = 0.5 and the paper's start (d0(0) = 4000 m even where the plane is deeper).",
           ""]
    rows = []
    bins = [("altitude < 300 m", p.altitude < 300), ("altitude >= 300 m", p.altitude >= 300),
            ("true d0 < 4000 m", p.truth_d0 < 4000), ("true d0 >= 4000 m", p.truth_d0 >= 4000),
            ("all", p.altitude > -np.inf)]
    for name, sel in bins:
        pp = p[sel]
        mm = m[m.set_index(["seed", "beacon"]).index.isin(pp.set_index(["seed", "beacon"]).index)]
        rows.append([name, frac(pp), mode_summary(pp), frac(mm)])
    out += [md_table(["subset", "paper found", "paper failure modes", "mixture found"], rows), ""]
    return out


def section_anatomy(frames):
    """Section 7: what each outcome looks like, over every paper-EM fit of the grids."""
    df = pd.concat([f for f in frames if "mode" in f and "method" in f], ignore_index=True)
    df = df[df.method == "paper"]
    rows = []
    for m in MODES:
        c = df[df["mode"] == m]
        if not len(c):
            continue
        rows.append([m, len(c), f"{int(round(c.err.median()))}", f"{c.sigma_mp.median():.3g}",
                     f"{c.mp_dp_gap_fit.median():.3g}", fmt(c.p_mp.median(), 3),
                     fmt(c.p_ol.median(), 3)])
    return ["## 7. Anatomy of the outcomes", "",
            f"All {len(df)} paper-EM fits of sections 1, 2, 4, 5 and 6 pooled. 'MP-DP gap' is "
            "the median over ranges of |predicted multipath range at the fitted d0 - direct "
            "path|: near 0 the multipath model has become a copy of the direct path.", "",
            md_table(["outcome", "fits", "median d0 - true (m)", "median sigma_MP (m)",
                      "median MP-DP gap (m)", "median mean P(MP)", "median mean P(OL)"], rows),
            ""]


def section_mechanism(traces, fixed_points, pol_crit, frozen):
    out = ["## Mechanism tables", "",
           "### A. Eq. 8 step by step (ABE58-like seed 1, Pol = 0.05, alpha = 0.5)", "",
           "g_DP / g_MP / g_OL: mean gamma_MP of the ranges whose true class is DP / MP / OL; "
           "DP share: fraction of the eq. 8 weight carried by true-DP ranges; eq. 8 avg: the "
           "gamma_MP-weighted mean of d0(k) before the alpha blend. The trace re-runs the "
           "library's `paper_e_step` / `paper_m_step`; its final d0 is compared with "
           "`fit_paper_em` on the same data.", ""]
    for name, (tr, info, fit_d0) in traces.items():
        last = int(tr["iter"].max())
        keep = sorted({0, 1, 2, 3, 5, 8, 12, 20, 40, last} & set(tr["iter"]))
        rows = []
        for _, r in tr[tr["iter"].isin(keep)].iterrows():
            rows.append([int(r["iter"]), f"{r.d0:.0f}", f"{r.sigma_mp:.3g}",
                         fmt(r.get("g_dp"), 2), fmt(r.get("g_mp"), 2), fmt(r.get("g_ol"), 2),
                         fmt(r.get("dp_share"), 2), fmt(r.get("eq8_avg"), 0)])
        final = float(tr["d0"].iloc[-1])
        out += [f"**{name}**: {100 * info['dp_finite']:.0f} % of the true-DP ranges have a "
                f"real d0(k) (median {info['dp_d0k_median']:.0f} m); true-MP ranges: median "
                f"d0(k) = {info['mp_d0k_median']:.0f} m. Final state after {last} iterations "
                f"(|trace - fit_paper_em| = {abs(final - fit_d0):.2g} m).",
                "",
                md_table(["iter", "d0", "sigma_MP", "g_DP", "g_MP", "g_OL", "DP share",
                          "eq. 8 avg"], rows), ""]
    out += ["### B. Where eq. 9 settles for a clean multipath cluster", "",
            "Idealisation: infinitely many multipath ranges N(0, s^2) around the right plane, no "
            "direct path nearby, d0 exact. With the current sigma_MP = t s, a range at "
            "residual r gets gamma_MP = p / (p + min(Pol, 1 - p)), "
            "p = erfc(|r| / (sqrt(2) t s)), and eq. 9 returns sqrt(E[gamma r^2] / E[gamma]). "
            "Iterating from t = 100:", "",
            md_table(["Pol", "fixed point sigma_MP / s"],
                     [[f"{pol:g}", fmt(t, 3)] for pol, t in fixed_points]), "",
            f"Above Pol ~ {pol_crit:.3f} no non-zero fixed point is left and sigma_MP "
            "collapses to 0.", "",
            "### C. Same, on simulated beacon 4: d0 frozen at the true plane vs free", "",
            f"{frozen.seed.nunique()} seeds. Frozen: alpha = 1e-9, d0(0) = true plane, "
            "sigma_MP(0) = 100 m (d0 cannot move). Free: the paper's EM as in section 3 "
            "(median over the fits that found the plane).", ""]
    rows = []
    s_true = float(frozen.truth_sigma_mp.iloc[0])
    for pol, t in fixed_points:
        c = frozen[frozen.pol == pol]
        ok = c.free_mode == "found"
        rows.append([f"{pol:g}", fmt(t * s_true), fmt(c.frozen_sigma.median()),
                     fmt(c.free_sigma[ok].median() if ok.any() else np.nan),
                     f"{int((c.free_mode == 'found').sum())}/{len(c)}",
                     f"{int((c.free_sigma[ok] < COLLAPSE_M).sum())}/{int(ok.sum())}"])
    out += [md_table(["Pol", "ideal sigma (m)", "frozen-d0 sigma (m)", "free sigma (m)",
                      "free found", f"of those, sigma < {COLLAPSE_M:g} m"], rows), ""]
    return out


def file_hash(path):
    """Short sha256 of a source file (src/ is being edited by others)."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:12]
    except OSError:
        return "n/a"


def render(results, args, runtime, explanation):
    """The full markdown document."""
    n = args.seeds
    argv = ["python", *sys.argv]
    try:
        argv[1] = str(Path(argv[1]).resolve().relative_to(ROOT))
    except ValueError:
        pass
    src = ROOT / "src" / "bayes_mpem"
    # frozen-grid rows hold two fits each
    n_fits = sum(len(d) for d in results["frames"]) + len(results["frozen"])
    lines = [
        "# The paper's EM: where it finds the reflecting plane and where it does not", "",
        "Generated by `benchmarks/paper_em_regimes.py` (tables) plus a hand-written "
        "explanation (between the markers, kept across reruns).", "",
        f"- Command: `{shlex.join(argv)}` (run from the repository root)",
        f"- Date: {_dt.datetime.now().astimezone().isoformat(timespec='seconds')}",
        f"- Runtime: {runtime:.0f} s on 1 core; {n_fits} fits",
        f"- Seeds: {args.seed0} .. {args.seed0 + n - 1} ({n} per cell); random preset seeds "
        f"{args.seed0} .. {args.seed0 + args.random_seeds - 1}",
        f"- bayes_mpem {bm.__version__}, numpy {np.__version__}; lbl/em_paper.py sha256 "
        f"{file_hash(src / 'lbl' / 'em_paper.py')}, lbl/simulate.py "
        f"{file_hash(src / 'lbl' / 'simulate.py')}, lbl/geometry.py "
        f"{file_hash(src / 'lbl' / 'geometry.py')}",
        f"- Success: |d0 - true d0| < {SUCCESS_M:g} m. Failure modes (first rule that "
        f"matches): **broad** = broad fixed point, sigma_MP > {BROAD_M:g} m; **captured** = "
        f"captured by the direct path, d0 within {CAPTURE_M:g} m of the median of "
        f"z_beacon - z_vehicle; **collapse** = sigma_MP < {COLLAPSE_M:g} m, d0 elsewhere; "
        f"**near** = |d0 - true d0| < {NEAR_M:g} m; **start** = stuck within {START_M:g} m "
        "of the starting d0(0); **other**.",
        "- Paper's EM defaults here: sigma_DP = 3.97 m (known, as in the paper), "
        "sigma_MP^2(0) = 1e7 m^2, d0(0) = 4000 m, tol = 1e-3 m, max_iter = 2000, triangle path.",
        "",
        BEGIN, explanation.strip(), END, "",
        "# Results", "",
    ]
    lines += section_weights(results["weights"], n)
    lines += section_pol_alpha(results["pol_alpha"], n)
    lines += section_claims(results["pol_alpha"], n)
    lines += section_geometry(results["altitude"], results["distance"], n)
    lines += section_init(results["init"], n)
    lines += section_random(results["random"], args.random_seeds)
    lines += section_anatomy(results["frames"])
    lines += section_mechanism(results["traces"], results["fixed_points"], results["pol_crit"],
                               results["frozen"])
    return "\n".join(lines).rstrip() + "\n"


def existing_explanation(path):
    """The hand-written block of an existing doc, or a placeholder."""
    try:
        text = Path(path).read_text()
    except OSError:
        text = ""
    if BEGIN in text and END in text:
        return text.split(BEGIN, 1)[1].split(END, 1)[0]
    return "_(explanation to be written)_"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="3 seeds per cell (10 random surveys); print instead of writing the doc")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per cell (default 20)")
    ap.add_argument("--random-seeds", type=int, default=None,
                    help="surveys of the random preset (default 60)")
    ap.add_argument("--seed0", type=int, default=0, help="first seed (default 0)")
    ap.add_argument("--out", type=Path, default=None,
                    help=f"markdown output (default {DEFAULT_OUT.relative_to(ROOT)})")
    ap.add_argument("--csv", type=Path, default=None, help="also write every fit to this CSV")
    args = ap.parse_args(argv)
    if args.seeds is None:
        args.seeds = 3 if args.quick else 20
    if args.random_seeds is None:
        args.random_seeds = 10 if args.quick else 60
    seeds = list(range(args.seed0, args.seed0 + args.seeds))
    rseeds = list(range(args.seed0, args.seed0 + args.random_seeds))

    t0 = time.perf_counter()
    results = {}
    steps = [("weights", lambda: grid_weights(seeds)),
             ("pol_alpha", lambda: grid_pol_alpha(seeds)),
             ("altitude", lambda: grid_altitude(seeds)),
             ("distance", lambda: grid_distance(seeds)),
             ("init", lambda: grid_init(seeds)),
             ("random", lambda: grid_random(rseeds)),
             ("frozen", lambda: grid_frozen(seeds))]
    for name, fn in steps:
        t = time.perf_counter()
        results[name] = fn()
        print(f"{name}: {len(results[name])} fits in {time.perf_counter() - t:.1f} s",
              file=sys.stderr)
    results["traces"] = {}
    for b, alt in (("1", 30.0), ("4", 30.0), ("4", 300.0)):
        sim = bm.simulate_survey("abe58", rng=1, altitude=alt)
        labels = sim.survey.table["true_class"].to_numpy()
        data = sim.survey.for_beacon(b)
        tr, info = trace_paper_em(data, labels[data.rows])
        fit_d0 = run_fit(data, sim.truth[b])["d0"]
        results["traces"][f"Beacon {b}, altitude {alt:g} m"] = (tr, info, fit_d0)
    results["fixed_points"] = [(pol, sigma_fixed_point(pol)) for pol in POLS]
    results["pol_crit"] = critical_pol()
    results["frames"] = [results[k] for k, _ in steps]  # for the fit count and --csv
    runtime = time.perf_counter() - t0

    out = args.out if args.out is not None else (None if args.quick else DEFAULT_OUT)
    text = render(results, args, runtime, existing_explanation(out or DEFAULT_OUT))
    if out is None:
        print(text)
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        print(f"wrote {out} ({runtime:.0f} s)", file=sys.stderr)
    if args.csv is not None:
        frames = [df.assign(grid=k) for k, df in zip([k for k, _ in steps], results["frames"],
                                                        strict=True)]
        pd.concat(frames, ignore_index=True).to_csv(args.csv, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
