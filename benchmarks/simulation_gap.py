"""What the simulation gets wrong: measured survey residuals against simulated replicates.

Run from the repository root::

    python benchmarks/simulation_gap.py            # writes docs/simulation-gap.md and figures
    python benchmarks/simulation_gap.py --quick    # 20 replicates, prints only

For each measured survey (the four OBSrange deck-box logs and the four SeaGap
transponders) every transponder is located by EM with straight rays and one
sound speed, ``N`` replicates are simulated under the simulator's assumptions
from the located fit (same track; ``bayes_mpem.survey_in.simcheck.simulate_like``), each
replicate is located in the same way, and the statistics of
``bayes_mpem.survey_in.gap_statistics.gap_statistics`` are compared (Monte-Carlo p-values).
Beside that, the part of refracted travel times (through the survey's profile)
that a straight-ray fit cannot absorb is computed for every ping
(``simcheck.refracted_twtt`` and ``simcheck.unabsorbed``).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from bayes_mpem.acoustics.profile import SoundSpeedProfile  # noqa: E402
from bayes_mpem.io.formats import read_survey  # noqa: E402
from bayes_mpem.survey_in.location import DEFAULT_TAT  # noqa: E402
from bayes_mpem.survey_in.simcheck import (  # noqa: E402  # noqa: E402
    STATISTICS,
    mc_pvalue,
    refracted_twtt,
    remove_common_drift,
    simulation_gap,  # noqa: E402
    unabsorbed,
)

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"
#: (label, file, format, profile): profile "ss_prof" (SeaGap's own), a file, or "woa09"
SURVEYS = [("SIO_CC03", DATA / "obsrange" / "SIO_CC03.txt", "obsrange-sio",
            DATA / "obsrange" / "CC03_ssp.txt"),
           ("SIO_EC03", DATA / "obsrange" / "SIO_EC03.txt", "obsrange-sio", "woa09"),
           ("SIO_WC03", DATA / "obsrange" / "SIO_WC03.txt", "obsrange-sio", "woa09"),
           ("WHOI_S05", DATA / "obsrange" / "WHOI_S05.txt", "obsrange-whoi", "woa09"),
           ("SeaGap", DATA / "seagap" / "obsdata.inp", "seagap", "ss_prof")]
SEAGAP_TRANSDUCER_DEPTH = 3.0  # m below the sea surface (SeaGap's XDUCER_DEPTH)
N_BINS = 6
SEED = 20260


def _profile(raw, spec):
    if spec == "ss_prof":
        p = raw.header["ss_prof"]
        return SoundSpeedProfile(p["depth"], p["sound_speed"], source="ss_prof.inp")
    if spec == "woa09":
        return SoundSpeedProfile.from_woa09(raw.header["lat"], raw.header["lon"],
                                            directory=DATA / "woa09")
    return SoundSpeedProfile.from_file(spec)


def refraction(pings, gap, prof, surface_depth):
    """Refraction signature per transponder: what a straight-ray fit cannot absorb.

    The profile is scaled so that its harmonic mean from the mean transducer depth to
    the transponder equals the fitted sound speed: the signature is then the bending
    of the rays, not a mismatch of the mean speed (reported as ``mean_speed``).
    """
    out, frames = {}, {}
    for tid, fit in gap.fits.items():
        fr = gap.frames[tid]
        z_ship = float(fr["depth"].mean()) - surface_depth
        mean_speed = float(prof.harmonic_mean(z_ship, fit.depth - surface_depth))
        scaled = SoundSpeedProfile(prof.depths, prof.speeds * fit.sound_speed / mean_speed,
                                   source=prof.source)
        twtt = refracted_twtt(pings, fit, scaled, surface_depth=surface_depth)
        if not np.all(np.isfinite(twtt)):
            raise RuntimeError(f"{tid}: rays without a direct eigenray")
        sig, shift = unabsorbed(pings, fit, twtt)
        tr = fr["true"].to_numpy()
        r = fr["residual"].to_numpy()
        groups = np.array_split(np.argsort(fr.loc[tr, "elevation"].to_numpy(), kind="stable"),
                                N_BINS)
        s2 = np.mean(r[tr] ** 2)
        lam = sum(g.size * np.mean(sig[tr][g]) ** 2 for g in groups) / s2
        out[tid] = {"signature": sig, "shift": shift, "mean_speed": mean_speed,
                    "rms_ms": 1e3 * np.sqrt(np.mean(sig**2)),
                    "peak_ms": 1e3 * np.max(np.abs(sig)), "lambda": float(lam)}
        frames[tid] = fr.assign(residual=sig)
    if len(frames) > 1:  # the same common-drift removal as the residuals'
        det = remove_common_drift(frames)
        for tid, f in det.items():
            d = f["detrended"].to_numpy()
            m = gap.frames[tid]["detrended"].to_numpy()
            ok = np.isfinite(d) & np.isfinite(m)
            out[tid]["det_rms_ms"] = 1e3 * np.sqrt(np.mean(d[ok] ** 2))
            out[tid]["meas_det_rms_ms"] = 1e3 * np.sqrt(np.mean(m[ok] ** 2))
            out[tid]["amplitude"] = float(np.sum(m[ok] * d[ok]) / np.sum(d[ok] ** 2))
    return out


def curvature_shift(pings, fit, R=6371000.0):
    """Depth/speed shift of a flat straight-ray fit to chord times on a sphere (SeaGap)."""
    sub = pings.iloc[fit.rows]
    x, y, z = (sub[c].to_numpy(float) for c in ("x", "y", "depth"))
    h = np.hypot(x - fit.east, y - fit.north)
    rb, rc = R - z, R - fit.depth
    chord = np.sqrt((rb - rc) ** 2 + 4 * rb * rc * np.sin(h / R / 2) ** 2)
    sig, shift = unabsorbed(pings, fit, 2 * chord / fit.sound_speed + fit.tat)
    return shift, 1e3 * np.sqrt(np.mean(sig**2))


def along_track(gap, tid, pings, heading=None):
    """rms of the true residuals before/after the fitted along-course offset; ship speed.

    With ``heading`` (degrees, one per ping of the table), also the rms after a
    two-component (forward, starboard) offset rotated by the logged heading.
    """
    fr = gap.frames[tid]
    f = fr[fr["true"]]
    r = f["residual"].to_numpy()
    a = np.column_stack([f["dtwtt_dforward"], np.ones(len(f))])
    coef, *_ = np.linalg.lstsq(a, r, rcond=None)
    after = r - a @ coef
    sub = pings.iloc[gap.fits[tid].rows].sort_values("time")
    dtm = np.diff(sub["time"].to_numpy())
    ok = dtm > 0
    v = np.hypot(np.diff(sub["x"].to_numpy()), np.diff(sub["y"].to_numpy()))[ok] / dtm[ok]
    out = {"before": 1e3 * np.std(r), "after": 1e3 * np.std(after), "offset": float(coef[0]),
           "speed": float(np.median(v))}
    if heading is not None:
        fit = gap.fits[tid]
        hd = np.radians(np.asarray(heading, float)[f["row"].to_numpy()])
        dx, dy = f["x"].to_numpy() - fit.east, f["y"].to_numpy() - fit.north
        k = 2.0 / (f["slant_range"].to_numpy() * fit.sound_speed)
        a2 = np.column_stack([k * (dx * np.sin(hd) + dy * np.cos(hd)),
                              k * (dx * np.cos(hd) - dy * np.sin(hd)), np.ones(len(f))])
        c2, *_ = np.linalg.lstsq(a2, r, rcond=None)
        out["after_heading"] = 1e3 * np.std(r - a2 @ c2)
        out["heading_offset"] = (float(c2[0]), float(c2[1]))
    return out


def _fmt(v, stat):
    if not np.isfinite(v):
        return "-"
    if stat in ("elevation", "slant_range", "time", "elevation_detrended",
                "slant_range_detrended"):
        return f"{v:.1f}"
    if stat in ("common_drift",):
        return f"{v:.3f}"
    return f"{v:.2f}"


def _pfmt(p):
    if not np.isfinite(p):
        return "-"
    return f"**{p:.3f}**" if p < 0.05 else (f"{p:.3f}" if p < 0.1 else f"{p:.2f}")


def fig_residuals(results, sigs, path):
    rows = [(lab, tid) for lab, g in results.items() for tid in g.fits]
    fig, axes = plt.subplots(len(rows), 4, figsize=(14, 2.1 * len(rows)), squeeze=False,
                             layout="constrained")
    cols = [("elevation", "measured"), ("elevation", "simulated"),
            ("slant_range", "measured"), ("slant_range", "simulated")]
    for i, (lab, tid) in enumerate(rows):
        g = results[lab]
        fm, fs = g.frames[tid], g.example[tid]
        fm, fs = fm[fm["true"]], fs[fs["true"]]
        lim = 1.05e3 * max(np.quantile(np.abs(fm["residual"]), 0.995),
                           np.quantile(np.abs(fs["residual"]), 0.995))
        hours = max(fm["time"].max(), 1.0) / 3600
        for j, (var, which) in enumerate(cols):
            ax = axes[i, j]
            f = fm if which == "measured" else fs
            v, r = f[var].to_numpy(), 1e3 * f["residual"].to_numpy()
            if var == "slant_range":
                v = v / 1e3
            sc = ax.scatter(v, r, c=f["time"] / 3600, s=3, cmap="viridis", vmin=0, vmax=hours,
                            rasterized=True)
            groups = np.array_split(np.argsort(v, kind="stable"), N_BINS)
            rms = np.sqrt(np.mean(r**2))
            ax.errorbar([np.mean(v[k]) for k in groups], [np.mean(r[k]) for k in groups],
                        [rms / np.sqrt(k.size) for k in groups], fmt="o", color="k", ms=4,
                        capsize=2, zorder=3)
            if which == "measured" and tid in sigs.get(lab, {}):
                sig = 1e3 * sigs[lab][tid]["signature"][g.frames[tid]["true"].to_numpy()]
                k = np.argsort(v)
                ax.plot(v[k], sig[k], ".", color="C3", ms=1.5, zorder=4)
            ax.axhline(0, color="0.5", lw=0.6)
            ax.set_ylim(-lim, lim)
            if i == 0:
                ax.set_title(f"{which}: residual vs "
                             f"{'elevation (deg)' if var == 'elevation' else 'slant range (km)'}",
                             fontsize=9)
            if j == 0:
                ax.set_ylabel(f"{lab} {tid}\nresidual (ms)" if lab != tid else
                              f"{lab}\nresidual (ms)", fontsize=8)
            ax.tick_params(labelsize=7)
        fig.colorbar(sc, ax=axes[i, :].tolist(), pad=0.01, fraction=0.02).set_label(
            "time (h)", fontsize=7)
    fig.suptitle("True-ping residuals, measured and one simulated replicate (same track).\n"
                 "Black: means of 6 equal-count bins +- rms/sqrt(n); red: refraction through "
                 "the profile, the part a straight-ray fit cannot absorb", fontsize=9)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def fig_spurious(results, path):
    labs = [lab for lab, g in results.items() if any((~g.frames[t]["true"]).any()
                                                     for t in g.fits)]
    fig, axes = plt.subplots(1, len(labs), figsize=(3.4 * len(labs), 3.0), squeeze=False)
    for ax, lab in zip(axes[0], labs, strict=True):
        g = results[lab]
        tid = next(iter(g.fits))
        sim = np.concatenate(g.spurious_ratio[tid])
        meas = g.frames[tid].loc[~g.frames[tid]["true"], "ratio"].to_numpy()
        bins = np.linspace(0, max(2.3, sim.max(), meas.max()) * 1.02, 47)
        ax.hist(sim, bins=bins, density=True, color="0.75", label=f"simulated ({g.n_sim} reps)")
        for m in meas:
            ax.axvline(m, color="C3", lw=1.5)
        ax.axvline(1.0, color="k", ls="--", lw=0.8)
        late = np.mean(meas > 1)
        sl = [np.mean(r > 1) for r in g.spurious_ratio[tid] if r.size]
        ax.set_title(f"{lab}: {meas.size} spurious, late share {late:.2f}\n"
                     f"simulated median {np.median(sl):.2f}", fontsize=8)
        ax.set_xlabel("observed / predicted travel time", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].plot([], [], color="C3", label="measured")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def fig_time(results, path):
    fig, axes = plt.subplots(len(results), 2, figsize=(12, 2.2 * len(results)), squeeze=False)
    for i, (lab, g) in enumerate(results.items()):
        lim = 0.0
        for j, frames in enumerate((g.frames, g.example)):
            ax = axes[i, j]
            for k, (tid, f) in enumerate(frames.items()):
                f = f[f["true"]].sort_values("time")
                r = 1e3 * f["residual"].to_numpy()
                ax.plot(f["time"] / 3600, r, ".", ms=2, color=f"C{k}",
                        label=tid if len(frames) > 1 else None, rasterized=True)
                lim = max(lim, 1.05 * np.quantile(np.abs(r), 0.995))
            ax.axhline(0, color="0.5", lw=0.6)
            ax.set_title(f"{lab}, {'measured' if j == 0 else 'one simulated replicate'}",
                         fontsize=8)
            ax.tick_params(labelsize=7)
            if j == 0:
                ax.set_ylabel("residual (ms)", fontsize=8)
            if len(frames) > 1 and j == 0:
                ax.legend(fontsize=6, markerscale=3, ncol=4)
        for ax in axes[i]:
            ax.set_ylim(-lim, lim)
    for ax in axes[-1]:
        ax.set_xlabel("time (h)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    """Command-line entry point."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="20 replicates; print only")
    p.add_argument("--n-sim", type=int, default=1000)
    p.add_argument("--out", default=str(ROOT / "docs" / "simulation-gap.md"))
    args = p.parse_args(argv)
    n_sim = 20 if args.quick else args.n_sim
    t_start = time.perf_counter()
    results, sigs, pings_of, extra, headings = {}, {}, {}, {}, {}
    for k, (lab, path, fmt, prof_spec) in enumerate(SURVEYS):
        raw = read_survey(path, fmt)
        pings, beacons = raw.to_pings()
        tat = raw.header.get("tat", 0.0 if fmt == "seagap" else DEFAULT_TAT)
        t0 = time.perf_counter()
        g = simulation_gap(pings, beacons, n_sim=n_sim, rng=SEED + k, n_bins=N_BINS, tat=tat)
        el = time.perf_counter() - t0
        results[lab], pings_of[lab] = g, pings
        if "heading" in raw.pings.columns:  # WHOI logs the ship's heading (same row order)
            headings[lab] = raw.pings["heading"].to_numpy(float)
        prof = _profile(raw, prof_spec)
        surface = (float(pings["depth"].mean()) - SEAGAP_TRANSDUCER_DEPTH if fmt == "seagap"
                   else 0.0)
        sigs[lab] = refraction(pings, g, prof, surface)
        src = prof.source.replace(str(ROOT) + "/", "")
        extra[lab] = {"seconds": el, "profile": src, "tat": tat}
        for tid, f in g.fits.items():
            fr = g.frames[tid]
            print(f"{lab} {tid}: {len(fr)} pings, {int((~fr['true']).sum())} spurious, "
                  f"c {f.sound_speed:.2f} m/s, depth {f.depth:.2f} m, sigma "
                  f"{1e3 * f.sigma:.3f} ms; survey: {n_sim} replicates in {el:.1f} s "
                  f"({g.n_warned} replicate fits warned)")
    tab = pd.concat([g.table.assign(survey=lab) for lab, g in results.items()],
                    ignore_index=True)
    # pooled late share over the deck-box logs (replicates are independent between surveys)
    deck = [lab for lab in results if lab != "SeaGap"]
    m_late = sum(int((results[lab].frames[t].loc[~results[lab].frames[t]["true"], "ratio"]
                      > 1).sum()) for lab in deck for t in results[lab].fits)
    m_spur = sum(int((~results[lab].frames[t]["true"]).sum()) for lab in deck
                 for t in results[lab].fits)
    s_share = []
    for i in range(n_sim):
        late = spur = 0
        for lab in deck:
            for t in results[lab].fits:
                r = results[lab].spurious_ratio[t][i]
                late, spur = late + int(np.sum(r > 1)), spur + r.size
        s_share.append(late / spur if spur else np.nan)
    s_share = np.array(s_share)
    pooled = {"late": m_late, "spurious": m_spur, "share": m_late / m_spur,
              "q": np.nanquantile(s_share, [0.05, 0.5, 0.95]),
              "p_lower": mc_pvalue(m_late / m_spur, s_share, "lower"),
              "p": mc_pvalue(m_late / m_spur, s_share, "two-sided")}
    total = time.perf_counter() - t_start  # simulations and fits; the page gives the whole run

    # ---------------------------------------------------------------- printout
    pd.set_option("display.width", 200)
    pd.set_option("display.max_rows", 500)
    show = tab[np.isfinite(tab["measured"])][["survey", "transponder", "statistic", "measured",
                                              "sim_q05", "sim_median", "sim_q95", "p_value"]]
    print(show.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"pooled deck-box spurious pings: {m_late} of {m_spur} late (share "
          f"{pooled['share']:.3f}); simulated 5/50/95 % {np.round(pooled['q'], 3)}; "
          f"p (fewer late) {pooled['p_lower']:.3f}, two-sided {pooled['p']:.3f}")
    for lab, d in sigs.items():
        for tid, s in d.items():
            print(f"refraction {lab} {tid}: profile mean {s['mean_speed']:.2f} m/s (scaled to "
                  f"the fit's), unabsorbed rms {s['rms_ms']:.4f} ms, peak "
                  f"{s['peak_ms']:.4f} ms, elevation noncentrality {s['lambda']:.2f}, depth "
                  f"shift {s['shift']['depth']:+.3f} m, c shift {s['shift']['sound_speed']:+.3f}"
                  + (f"; after common drift: signature {s['det_rms_ms']:.4f} ms, measured "
                     f"{s['meas_det_rms_ms']:.4f} ms, amplitude {s['amplitude']:.2f}"
                     if "amplitude" in s else ""))
    curv = {tid: curvature_shift(pings_of["SeaGap"], f)
            for tid, f in results["SeaGap"].fits.items()}
    for tid, (sh, rms) in curv.items():
        print(f"sphere SeaGap {tid}: depth shift {sh['depth']:+.3f} m, c "
              f"{sh['sound_speed']:+.3f} m/s, unabsorbed rms {rms:.5f} ms")
    at = {lab: along_track(results[lab], next(iter(results[lab].fits)), pings_of[lab],
                           heading=headings.get(lab)) for lab in deck}
    for lab, d in at.items():
        print(f"along-track {lab}: rms {d['before']:.3f} -> {d['after']:.3f} ms, offset "
              f"{d['offset']:+.2f} m, ship speed {d['speed']:.2f} m/s, equivalent time lag "
              f"{d['offset'] / d['speed']:+.2f} s"
              + (f"; with the logged heading (forward, starboard "
                 f"{d['heading_offset'][0]:+.2f}, {d['heading_offset'][1]:+.2f} m): "
                 f"{d['after_heading']:.3f} ms" if "after_heading" in d else ""))
    print(f"total {total:.1f} s")
    if args.quick:
        return

    # ---------------------------------------------------------------- figures
    figdir = Path(args.out).parent / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    fig_residuals(results, sigs, figdir / "simulation_gap_residuals.png")
    fig_spurious(results, figdir / "simulation_gap_spurious.png")
    fig_time(results, figdir / "simulation_gap_time.png")
    total = time.perf_counter() - t_start

    # ---------------------------------------------------------------- page
    def val(lab, tid, stat, col="measured"):
        r = tab[(tab.survey == lab) & (tab.transponder == tid) & (tab.statistic == stat)]
        return float(r[col].iloc[0])

    def pv(lab, tid, stat):
        return _pfmt(val(lab, tid, stat, "p_value"))

    def rng_str(xs, f="{:.2f}"):
        return f"{f.format(min(xs))} to {f.format(max(xs))}"

    sg = results["SeaGap"]
    sg_ids = list(sg.fits)
    sgs = {t: sigs["SeaGap"][t] for t in sg_ids}
    sg_rms = [1e3 * np.sqrt(np.mean(sg.frames[t].loc[sg.frames[t]["true"], "residual"] ** 2))
              for t in sg_ids]
    sg_cd = [curv[t][0]["depth"] for t in sg_ids]
    allsg = pd.concat([f[f["true"]] for f in sg.frames.values()])
    # the common drift in time: mean residual over the transponders at each shot, smoothed
    shot = allsg.groupby("time")["residual"].mean().sort_index()
    smooth = 1e3 * shot.rolling(31, center=True, min_periods=10).mean()
    low = allsg["elevation"] < 55
    t_low = allsg.loc[low, "time"].max() / 3600
    el_after = allsg.loc[allsg["time"] > allsg.loc[low, "time"].max(), "elevation"]
    span_h = (allsg["time"].max() - allsg["time"].min()) / 3600
    obs_sig = {lab: sigs[lab][next(iter(results[lab].fits))] for lab in deck}
    wh = at["WHOI_S05"]
    sio = [("SIO_CC03", "CC03"), ("SIO_EC03", "EC03"), ("SIO_WC03", "WC03")]
    deck_ids = [(lab, next(iter(results[lab].fits))) for lab in deck]

    def bin_means(lab, tid):
        f = results[lab].frames[tid]
        t = f[f["true"]]
        g = np.array_split(np.argsort(t["elevation"].to_numpy(), kind="stable"), N_BINS)
        sig = sigs[lab][tid]["signature"][f["true"].to_numpy()]
        return ([float(t["elevation"].iloc[k].mean()) for k in g],
                [1e3 * float(t["residual"].iloc[k].mean()) for k in g],
                [1e3 * float(np.mean(sig[k])) for k in g])

    cmd = "python benchmarks/simulation_gap.py" + (
        " " + " ".join(sys.argv[1:]) if argv is None and sys.argv[1:] else "")
    L = ["# What the simulation gets wrong: measured against simulated residuals", "",
         f"Produced by `{cmd}` on {dt.date.today().isoformat()} ({total:.0f} s on this machine; "
         f"{n_sim} replicates per survey, seeds {SEED}-{SEED + len(SURVEYS) - 1}). Library: "
         "`bayes_mpem.survey_in.simcheck`; tests: `tests/survey_in/test_simcheck.py`.", "",
         "## Method", "",
         "Every transponder of the five measured surveys is located by `locate` (EM, straight "
         "rays, one sound speed, spurious pings uniform over the listening window). The "
         "surveys are the OBSrange deck-box logs SIO CC03, EC03, WC03 and WHOI S05 (TAT "
         "13 ms) and the four SeaGap transponders (TAT 0). `simcheck.simulate_like` then draws "
         "replicate surveys under exactly the simulator's assumptions, from the located "
         "values:", "",
         "* the same ship track (positions, depths, times);",
         "* travel times of straight rays at the fitted sound speed, plus the TAT;",
         "* independent Gaussian noise of the fitted sigma;",
         "* each ping spurious with probability 1 - weight, and then uniform over the "
         "listening window.", "",
         "Every replicate is located again in the same way. This is like with like: the fit "
         "absorbs as much of a replicate as of the measured survey. The statistics below are "
         "computed from both. The Monte-Carlo p-value says how often the simulation produces "
         "a value as extreme as the measured one. It is one-sided for the binned chi-square "
         "statistics and the common drift, and two-sided otherwise. The smallest possible "
         f"value is {1 / (n_sim + 1):.4f} one-sided and {2 / (n_sim + 1):.4f} two-sided. "
         "p-values below 0.05 are in bold. With 8 transponders and 12 statistics, a few "
         "p-values near 0.05 are expected by chance.", "",
         "A residual is the observed minus the straight-ray predicted two-way travel time. "
         "Statistics use the pings with p_true >= 0.5 (true); the late share uses those with "
         "p_true < 0.5 (spurious). For a binned statistic the pings are sorted by the "
         f"variable and cut into {N_BINS} groups of equal count. The statistic is "
         "`sum n_b mean_b^2 / s^2`, with `s^2` the mean squared residual. For independent "
         f"noise before any fit it would be chi-square with {N_BINS} degrees of freedom; "
         "the simulated column shows what it is after the fit. Full definitions are in the "
         "`bayes_mpem.survey_in.simcheck` docstring.", "",
         "Refraction is computed for every ping: the two-way time along the refracted "
         "eigenray, at the located position, through the survey's profile. The profiles are "
         "SeaGap's `ss_prof.inp` (the sea surface 3 m above the mean transducer), OBSrange's "
         "`CC03_ssp.txt` for CC03, and the WOA09 climatology at the drop point for EC03, WC03 "
         "and S05. Each profile is scaled so that its harmonic mean down to the transponder "
         "equals the fitted sound speed, so that only the bending of the rays counts. A "
         "straight-ray fit (position, depth, sound speed) to those noise-free times leaves "
         "the part it cannot absorb (`simcheck.unabsorbed`): the red dots in the first "
         "figure.", ""]

    L += ["## Findings", ""]
    L += ["### 1. SeaGap: a drift in time common to all transponders, not noise", "",
          f"The residuals (rms {rng_str(sg_rms, '{:.3f}')} ms) follow one slow curve in time, "
          f"the same for all four transponders. Averaged over the transponders and 31 shots, "
          f"the curve runs from {smooth.min():+.2f} to {smooth.max():+.2f} ms over the "
          f"{span_h:.1f} h (third figure).", "",
          "Each residual can be predicted from the other transponders pinged at the same "
          "time: their mean residual over predicted travel time, times this ping's predicted "
          "time. That prediction removes "
          f"{rng_str([100 * val('SeaGap', t, 'common_drift') for t in sg_ids], '{:.1f}')} % "
          "of each transponder's residual variance, and leaves an rms of "
          f"{rng_str([s['meas_det_rms_ms'] for s in sgs.values()], '{:.3f}')} ms. In the "
          "simulation it removes nothing: the simulated share has a median of "
          f"{rng_str([val('SeaGap', t, 'common_drift', 'sim_median') for t in sg_ids])}, "
          "negative, as it must be for independent noise.", "",
          f"The lag-1 autocorrelation is "
          f"{rng_str([val('SeaGap', t, 'lag1') for t in sg_ids], '{:.3f}')}; simulated, the "
          f"5-95 % range is at most "
          f"{rng_str([val('SeaGap', t, 'lag1', 'sim_q05') for t in sg_ids] + [val('SeaGap', t, 'lag1', 'sim_q95') for t in sg_ids])}"  # noqa: E501
          ". The simulator's constant, independent noise of about 0.32 ms is in truth a "
          "sound speed that changes in time (SeaGap itself models this), on top of a "
          "measurement noise "
          f"{rng_str([r / s['meas_det_rms_ms'] for r, s in zip(sg_rms, sgs.values(), strict=True)], '{:.0f}')}"  # noqa: E501
          " times smaller.", "",
          "What is left after the common drift is still autocorrelated (lag 1 "
          f"{rng_str([val('SeaGap', t, 'lag1_detrended') for t in sg_ids])}). It is a "
          "structure that one mean over the transponders cannot remove, possibly a horizontal "
          "sound-speed gradient; this page does not test that.", ""]
    L += ["### 2. Elevation angle and slant range: on SeaGap it is the drift, not refraction",
          "",
          "On SeaGap the binned elevation statistics are "
          f"{rng_str([val('SeaGap', t, 'elevation') for t in sg_ids], '{:.0f}')} and the "
          "slant-range ones "
          f"{rng_str([val('SeaGap', t, 'slant_range') for t in sg_ids], '{:.0f}')}, against "
          "a simulated 95th percentile of at most "
          f"{max(val('SeaGap', t, 'elevation', 'sim_q95') for t in sg_ids):.0f}. All are "
          "flagged. But elevation and time are confounded by the track. Every ping below 55 "
          f"degrees of elevation was recorded in the first {t_low:.1f} h, on the square "
          f"track; after that, 90 % of the pings lie between {el_after.quantile(0.05):.0f} "
          f"and {el_after.quantile(0.95):.0f} degrees. The time statistic is larger still "
          f"({rng_str([val('SeaGap', t, 'time') for t in sg_ids], '{:.0f}')}).", "",
          "Refraction through `ss_prof.inp` cannot explain it. After the straight-ray fit has "
          "absorbed what it can, refraction leaves "
          f"{rng_str([s['rms_ms'] for s in sgs.values()], '{:.3f}')} ms rms, at most "
          f"{max(s['peak_ms'] for s in sgs.values()):.3f} ms. Alone, it would add "
          f"{rng_str([s['lambda'] for s in sgs.values()])} to the elevation statistic, "
          "against a measured excess in the hundreds.", "",
          "After the common drift is removed, the elevation statistic is still "
          + ", ".join(_fmt(val("SeaGap", t, "elevation_detrended"), "elevation")
                      for t in sg_ids)
          + " (p " + ", ".join(pv("SeaGap", t, "elevation_detrended") for t in sg_ids)
          + "). Those residuals are autocorrelated, and autocorrelation inflates any binned "
          "statistic. After the same drift removal, the refraction signature has an rms of "
          f"{rng_str([s['det_rms_ms'] for s in sgs.values()], '{:.4f}')} ms, against "
          f"{rng_str([s['meas_det_rms_ms'] for s in sgs.values()], '{:.3f}')} ms measured. "
          "Fitted to the measured residuals, it gets amplitudes of "
          + ", ".join(f"{s['amplitude']:.1f}" for s in sgs.values())
          + " (1 would be the profile's refraction, 0 none). These statistics cannot "
          "separate refraction from the autocorrelated remainder. A held-out likelihood "
          "comparison that models the drift as a B-spline in time can: there, refraction "
          "through `ss_prof.inp` gains +12 to +46 nats per transponder "
          "([measured data](measured-data.md), `benchmarks/measured_gain.py`). So "
          "refraction is in the SeaGap data, at a level of hundredths of a millisecond, "
          "under a drift more than ten times larger.", "",
          "On the deck-box logs, refraction leaves "
          f"{rng_str([s['rms_ms'] for s in obs_sig.values()], '{:.4f}')} ms rms. Their "
          "elevations are all above 54 degrees, their noise is 1.5-4.6 ms, and their travel "
          "times are logged to 1 ms, so refraction cannot be seen there. The elevation and "
          "slant-range statistics are nevertheless flagged on CC03 (p "
          f"{pv('SIO_CC03', 'CC03', 'elevation')}, {pv('SIO_CC03', 'CC03', 'slant_range')}) "
          f"and EC03 (p {pv('SIO_EC03', 'EC03', 'elevation')}, "
          f"{pv('SIO_EC03', 'EC03', 'slant_range')}). WC03 "
          f"(p {pv('SIO_WC03', 'WC03', 'elevation')}) and WHOI S05 "
          f"(p {pv('WHOI_S05', 'S05', 'elevation')}) are not flagged. The flagged bin means "
          "do not follow a trend. From the lowest to the highest elevation they are:", ""]
    for lab, tid in sio[:2]:
        e, m, _ = bin_means(lab, tid)
        L.append(f"* {lab}: " + ", ".join(f"{a:.0f} deg: {b:+.2f}" for a, b in
                                          zip(e, m, strict=True)) + " ms;")
    L += ["", "These zig-zag between neighbouring bins instead of following the smooth shape "
          "of refraction. The bins hold 8-15 pings each, and single large residuals move "
          "their means: CC03's residuals have an excess kurtosis of "
          f"{val('SIO_CC03', 'CC03', 'kurtosis'):.2f} (p {pv('SIO_CC03', 'CC03', 'kurtosis')})"
          ". Given the number of comparisons on this page, these two logs are weak evidence "
          "of a pattern, and not of refraction.", ""]
    L += ["### 3. Spurious returns arrive after the true one about as often as simulated", "",
          f"Over the four deck-box logs, {m_late} of {m_spur} spurious pings arrive after the "
          f"predicted true arrival (share {pooled['share']:.2f}). Simulated, the 5-95 % range "
          f"is {pooled['q'][0]:.2f}-{pooled['q'][2]:.2f}, with a median of "
          f"{pooled['q'][1]:.2f}; the p-value for as few late ones is "
          f"{pooled['p_lower']:.2f}. No single log's late share is outside its simulated "
          "range (table below).", "",
          "This test is weak by construction. The listening window is the range of the "
          "observed travel times (the logs do not give the deck box's), so the spurious pings "
          "themselves set its ends, and the simulation inherits where they are: EC03's "
          "window ends at its latest spurious ping, so the simulation puts nearly all its "
          "spurious pings late. Where the window's end is close to the true arrival (WHOI "
          "S05, SIO WC03), the simulation puts nearly all spurious pings early: "
          f"WHOI's simulated median share is {val('WHOI_S05', 'S05', 'late_share', 'sim_median'):.2f}"  # noqa: E501
          f" (p {pv('WHOI_S05', 'S05', 'late_share')} for its 0 of 10). So WHOI's ten early "
          "spurious pings do not contradict uniform spurious returns.", "",
          "The SIO logs' late ones show that the first-threshold-crossing argument fails "
          "there: CC03 has one at obs/pred 2.10, EC03 two at 1.10 and 1.22. A late return "
          "can be reported when the true arrival was not detected. The 2.10 is about twice "
          "the travel time, probably a reply that went round the sea surface and the "
          "seafloor once more.", ""]
    L += ["### 4. What else the simulation lacks", "",
          f"**WHOI S05: a position offset along the ship's course.** Its residuals (rms "
          f"{wh['before']:.2f} ms) rise and fall with each leg of the track. The lag-1 "
          f"autocorrelation is {val('WHOI_S05', 'S05', 'lag1'):.2f} (p "
          f"{pv('WHOI_S05', 'S05', 'lag1')}) and the time statistic "
          f"{val('WHOI_S05', 'S05', 'time'):.0f}. A single fitted offset of the acoustic "
          f"position along the course, {wh['offset']:+.1f} m (p "
          f"{pv('WHOI_S05', 'S05', 'along_track')}), brings the rms to {wh['after']:.2f} ms. "
          f"A forward and starboard offset turned by the logged heading does about as well: "
          f"{wh['heading_offset'][0]:+.1f} m forward, {wh['heading_offset'][1]:+.2f} m "
          f"starboard, rms {wh['after_heading']:.2f} ms.", "",
          f"At the ship's median speed of {wh['speed']:.2f} m/s, the same offset is also a "
          f"{wh['offset'] / wh['speed']:+.1f} s lag between the position fix and the ping. "
          "The two explanations cannot be told apart on this track. OBSrange fits a "
          "GPS-transducer offset and corrects for the ship's motion; `locate` does neither "
          "yet.", "",
          "The SIO logs show smaller offsets: "
          + ", ".join(f"{lab[4:]} {val(lab, t, 'along_track'):+.1f} m (p "
                      f"{pv(lab, t, 'along_track')})" for lab, t in sio) + ".", "",
          "**Noise that changes with elevation.** Take the log of the sd at the lowest third "
          "of elevations over the sd at the highest third. It is "
          + ", ".join(f"{lab} {_fmt(val(lab, t, 'noise_elevation'), 'x')} (p "
                      f"{pv(lab, t, 'noise_elevation')})" for lab, t in deck_ids)
          + ". WHOI's value comes from the along-course offset, whose effect grows with "
          "horizontal range. On SeaGap (p < 0.01 for every transponder, both signs) it comes "
          "from the drift.", "",
          "**Heavy tails.** The excess kurtosis of the true residuals is "
          + ", ".join(f"{lab} {_fmt(val(lab, t, 'kurtosis'), 'x')} (p "
                      f"{pv(lab, t, 'kurtosis')})" for lab, t in deck_ids)
          + "; SeaGap "
          + ", ".join(f"{_fmt(val('SeaGap', t, 'kurtosis'), 'x')} (p "
                      f"{pv('SeaGap', t, 'kurtosis')})" for t in sg_ids) + ".", "",
          "**Depth.** A straight-ray fit to the refracted times through `ss_prof.inp` puts "
          "the SeaGap transponders "
          f"{rng_str([s['shift']['depth'] for s in sgs.values()], '{:+.2f}')} m deeper than "
          "the rays' end point. Suppose SeaGap's horizontal coordinates are distances along "
          "the Earth (the convention `locate`'s `earth_radius` option follows). Then a "
          "flat-frame fit to chord travel times puts them a further "
          f"{rng_str(sg_cd, '{:+.2f}')} m deeper, and leaves no residual pattern: depth and "
          "sound speed absorb the curvature. Together that is about half of the measured "
          "1.3-1.7 m difference from SeaGap's initial values (fitted with the sphere, "
          "refraction and the time model together, the depths move by 0.84-1.22 m: "
          "[measured data](measured-data.md)). On the deck-box logs, "
          "refraction deepens the straight-ray fit by "
          f"{rng_str([s['shift']['depth'] for s in obs_sig.values()], '{:+.2f}')} m.", ""]
    L += ["### In plain words", "",
          "The simulation treats the travel-time error as constant, independent noise, and "
          "that is wrong on two of the three kinds of survey:", "",
          "* On the GNSS-acoustic survey, the error is mostly a slow change of the sound "
          "speed in time, shared by all transponders, over a noise "
          f"{rng_str([r / s['meas_det_rms_ms'] for r, s in zip(sg_rms, sgs.values(), strict=True)], '{:.0f}')}"  # noqa: E501
          " times smaller.",
          "* On the WHOI deck-box log, it is mostly a position offset along the ship's "
          "course.",
          "* The SIO logs are closest to the simulation: a few large residuals, and weak "
          "patterns that are not consistent from log to log.", "",
          "Refraction through the sound-speed profile was the effect to look for first. Once "
          "the straight-ray sound speed and depth have absorbed its mean, too little is left "
          "for these residual statistics to see under any of these errors. What they cannot "
          "see, a likelihood that models SeaGap's drift does find (measured data page), and "
          "the straight-ray depth is biased by a few decimetres. The timing of the spurious "
          "returns is what the simulation assumes.",
          "",
          "The named causes, in order of size:", "",
          "* a sound speed that changes in time (SeaGap);",
          "* a GPS-transducer offset, or a lag between the position fix and the ping (WHOI);",
          "* occasional large errors, heavy tails (SIO CC03);",
          "* below what these statistics detect: refraction (found on SeaGap only by the "
          "held-out likelihood once the drift is modelled) and, for the depth, the Earth's "
          "curvature.", ""]
    L += ["## Figures", "",
          "![Residuals against elevation and slant range](figures/simulation_gap_residuals.png)",
          "",
          "True-ping residuals against elevation angle and slant range, measured and one "
          "simulated replicate of the same track, coloured by time; black, binned means; "
          "red, the refraction signature.", "",
          "![Residuals in time](figures/simulation_gap_time.png)", "",
          "True-ping residuals in time, measured and one simulated replicate.", "",
          "![Spurious arrival times](figures/simulation_gap_spurious.png)", "",
          "Where the spurious returns arrive: observed over predicted travel time, measured "
          "(red lines) and pooled over the simulated replicates (grey); the dashed line is the "
          "true arrival.", ""]

    L += ["## Tables", "",
          "Each row: measured value, the 5-95 % range over the simulated replicates, and the "
          "Monte-Carlo p-value. `-`: undefined (no spurious ping; one transponder).", ""]
    for stat, (_, side, desc) in STATISTICS.items():
        sub = tab[tab.statistic == stat]
        sub = sub[np.isfinite(sub["measured"])]
        if sub.empty:
            continue
        L += [f"### `{stat}`: {desc} ({side})", "",
              "| survey | transponder | measured | simulated 5-95 % | p |",
              "|---|---|---:|---:|---:|"]
        for _, r in sub.iterrows():
            L.append(f"| {r.survey} | {r.transponder} | {_fmt(r.measured, stat)} | "
                     f"{_fmt(r.sim_q05, stat)} to {_fmt(r.sim_q95, stat)} | "
                     f"{_pfmt(r.p_value)} |")
        L.append("")
    L += ["### Pooled late share (the four deck-box logs)", "",
          "| late / spurious | share | simulated 5-95 % | p (fewer late) | p (two-sided) |",
          "|---:|---:|---:|---:|---:|",
          f"| {m_late} / {m_spur} | {pooled['share']:.2f} | {pooled['q'][0]:.2f} to "
          f"{pooled['q'][2]:.2f} | {_pfmt(pooled['p_lower'])} | {_pfmt(pooled['p'])} |", "",
          "### Refraction through the profile: what a straight-ray fit cannot absorb", "",
          "| survey | transponder | profile | its mean speed (m/s) | fitted c (m/s) | "
          "rms (ms) | peak (ms) | depth shift (m) | sound-speed shift (m/s) | "
          "elevation statistic added |",
          "|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for lab, d in sigs.items():
        for tid, s in d.items():
            L.append(f"| {lab} | {tid} | {extra[lab]['profile']} | {s['mean_speed']:.2f} | "
                     f"{results[lab].fits[tid].sound_speed:.2f} | {s['rms_ms']:.4f} | "
                     f"{s['peak_ms']:.4f} | {s['shift']['depth']:+.3f} | "
                     f"{s['shift']['sound_speed']:+.3f} | {s['lambda']:.2f} |")
    L += ["", "The profile is scaled from its own mean speed (harmonic mean from the mean "
          "transducer depth to the transponder) to the fitted c before the rays are traced. "
          "The depth and sound-speed shifts are what the straight-ray fit absorbs: the fit to "
          "the refracted times minus the position the rays were traced to. 'Elevation "
          "statistic added' is what the signature alone would add to the measured elevation "
          "statistic (same bins, same normalisation).", "",
          "### Mean residual per elevation bin (ms): measured and refraction", "",
          "| survey | transponder | bin mean elevations (deg) | measured (ms) | "
          "refraction (ms) |", "|---|---|---|---|---|"]
    for lab, g in results.items():
        for tid in g.fits:
            e, m, r = bin_means(lab, tid)
            L.append(f"| {lab} | {tid} | {', '.join(f'{v:.1f}' for v in e)} | "
                     f"{', '.join(f'{v:+.3f}' for v in m)} | "
                     f"{', '.join(f'{v:+.4f}' for v in r)} |")
    L += ["", "## Limits", "",
          "* The p-values are per statistic and per transponder. They are not corrected for "
          "the number of comparisons.",
          "* A binned statistic responds to any slow pattern. On an autocorrelated series "
          "(SeaGap) it can be flagged whatever the variable, so a flag alone does not name "
          "the cause; the time, along-course and refraction checks above do.",
          "* The late share is tested against a listening window taken from the data "
          "(point 3); the deck boxes' real windows would make it a sharper test.",
          "* The refraction signature uses one profile per survey (the WOA09 climatology for "
          "EC03, WC03 and S05) and the located position. The real profile at survey time "
          "differs, and changes in time (point 1).",
          "* The along-course offset is a one-parameter proxy for a lever arm or a time lag; "
          "`locate` fits neither.",
          "* SeaGap has no spurious pings (weight 1), so its late share is undefined.", ""]
    text = "\n".join(L)
    Path(args.out).write_text(text)
    print(f"wrote {args.out} and {figdir}/simulation_gap_*.png")


if __name__ == "__main__":
    main()
