"""Straight-ray plane heights over a refracting ocean: ABE dive 58 at mid-ocean ridges.

Run from the repository root::

    python benchmarks/ridge_refraction.py            # results section of docs/refraction.md
    python benchmarks/ridge_refraction.py --quick    # fewer seeds and speeds, prints only

For each ridge site the WOA09 annual profile of the nearest atlas cell is read,
the ``abe58`` preset (the paper's beacon depths, the vehicle 30 m above a
2,430 m floor) is simulated with refracted rays through it and the sea surface
as the reflector, the travel times are turned into ranges with a nominal sound
speed, and every beacon is fitted with the straight-ray mixture EM and with the
refracted one (same profile and nominal speed). Reported: plane height minus
beacon depth, next to the paper's Table II (0, +9, +9, +14 m). Also a scan of
the nominal speed, two other candidate explanations (a wrong nominal speed in
homogeneous water; beacon depths recorded wrongly), the cost, and the figures
``docs/figures/refraction_*.png``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402

import bayes_mpem as bm  # noqa: E402
from bayes_mpem.acoustics.eigenray import shoot, surface_bounce_ray  # noqa: E402
from bayes_mpem.acoustics.profile import SoundSpeedProfile  # noqa: E402
from bayes_mpem.acoustics.profile_checks import nominal_sound_speed  # noqa: E402
from bayes_mpem.acoustics.turning import direct_times  # noqa: E402
from bayes_mpem.lbl.em.em_mixture import fit_mixture_em  # noqa: E402
from bayes_mpem.lbl.simulation.presets import ABE58  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WOA09 = ROOT / "data" / "woa09"
BEACONS = ("1", "2", "3", "4")
DEPTHS = np.array([ABE58["beacons"][b]["depth"] for b in BEACONS])
TABLE2 = np.array([2392.0, 2500.0, 2404.0, 2486.0]) - DEPTHS  # 0, +9, +9, +14
SITES = [  # name, lat, lon, label
    ("Kairei", -25.32, 70.04, "Central Indian Ridge, Kairei (assumed ABE 58 site)"),
    ("Endeavour", 47.95, -129.10, "Juan de Fuca Ridge, Endeavour"),
    ("TAG", 26.14, -44.83, "Mid-Atlantic Ridge, TAG"),
    ("EPR", 9.83, -104.29, "East Pacific Rise, 9 50'N"),
]
SPEEDS = ("harmonic mean", "near-bottom", "1500 m/s")


def nominal_speeds(prof):
    """The three nominal speeds an LBL system may have used."""
    zb = float(DEPTHS.mean())
    return {"harmonic mean": nominal_sound_speed(prof, zb),
            "near-bottom": float(prof.speed(zb)), "1500 m/s": 1500.0}


def fit_survey(sim, prof=None, c_nom=None, refracted=True):
    """Straight (and refracted) mixture-EM offsets ``d0 - beacon depth`` of every beacon."""
    out = {"straight": [], "sigma_dp": [], "refracted": [], "se": []}
    for b in BEACONS:
        data = sim.survey.for_beacon(b)
        depth = float(data.position[2])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", bm.FitQualityWarning)
            r = fit_mixture_em(data, rng=0)
        out["straight"].append(r.d0 - depth)
        out["sigma_dp"].append(r.sigma_dp)
        out["se"].append(r.d0_se)
        if refracted and prof is not None:
            rr = fit_mixture_em(data, rng=0, ssp=prof, sound_speed=c_nom)
            assert rr.settings["refraction"]["no_ray"] == 0
            out["refracted"].append(rr.d0 - sim.truth[b]["d0"])
    return {k: np.array(v) for k, v in out.items()}


def run_site(prof, seeds):
    """Main table rows of one site: every nominal speed, several seeds."""
    rows = {}
    for name, c in nominal_speeds(prof).items():
        fits, turning = [], []
        for s in seeds:
            sim = bm.simulate_survey("abe58", rng=s, ssp=prof, sound_speed=c)
            fits.append(fit_survey(sim, prof, c))
            replies = [int(sim.survey.for_beacon(b).n) for b in BEACONS]
            turning.append(sum(sim.truth[b]["turning_direct"] for b in BEACONS) / sum(replies))
        rows[name] = {"c": c, "turning": float(np.mean(turning)),
                      **{k: np.array([f[k] for f in fits]) for k in fits[0]}}
    return rows


def scan_speeds(prof, speeds, seeds):
    """Straight-ray offsets (mean over seeds) and sigma_DP against the nominal speed."""
    off, sdp = [], []
    for c in speeds:
        fits = [fit_survey(bm.simulate_survey("abe58", rng=s, ssp=prof, sound_speed=c),
                           refracted=False) for s in seeds]
        off.append(np.mean([f["straight"] for f in fits], axis=0))
        sdp.append(np.mean([f["sigma_dp"] for f in fits], axis=0))
    return np.array(off), np.array(sdp)


def other_explanations(seeds, c_bottom):
    """A wrong nominal speed in homogeneous water; beacon depths recorded wrongly."""
    rows = []
    homog = SoundSpeedProfile.constant(c_bottom)
    for c_nom in (1500.0, c_bottom * 1.005):
        fits = [fit_survey(bm.simulate_survey("abe58", rng=s, ssp=homog, sound_speed=c_nom),
                           refracted=False) for s in seeds]
        rows.append((f"homogeneous {c_bottom:.1f} m/s water, nominal {c_nom:.1f} m/s "
                     f"({100 * (c_nom / c_bottom - 1):+.2f} %)", fits))
    for e in (-10.0, 10.0):
        beacons = {k: dict(v, depth=v["depth"] + e) for k, v in ABE58["beacons"].items()}
        fits = []
        for s in seeds:
            sim = bm.simulate_survey("abe58", rng=s, beacons=beacons)
            rec = sim.survey.beacons.reset_index()
            rec["depth"] = rec["depth"] - e
            survey = bm.load_survey(sim.survey.table, rec)
            fits.append(fit_survey(_Sim(survey), refracted=False))
        where = "deeper" if e > 0 else "shallower"
        rows.append((f"straight rays, each beacon {abs(e):.0f} m {where} than recorded", fits))
    return rows


class _Sim:
    def __init__(self, survey):
        self.survey = survey


def timings(prof, c):
    """Best of 5: simulation and one beacon's fit, straight and refracted."""
    def best(f, n=5):
        ts = []
        for _ in range(n):
            t0 = time.perf_counter()
            f()
            ts.append(time.perf_counter() - t0)
        return min(ts)

    sim = bm.simulate_survey("abe58", rng=0, ssp=prof, sound_speed=c)
    data = sim.survey.for_beacon("4")
    res = fit_mixture_em(data, rng=0, ssp=prof, sound_speed=c)
    return {
        "sim_straight": best(lambda: bm.simulate_survey("abe58", rng=0)),
        "sim_refracted": best(lambda: bm.simulate_survey("abe58", rng=0, ssp=prof,
                                                         sound_speed=c)),
        "fit_straight": best(lambda: fit_mixture_em(data, rng=0)),
        "fit_refracted": best(lambda: fit_mixture_em(data, rng=0, ssp=prof, sound_speed=c)),
        "n": data.n, "planes": res.settings["refraction"]["planes_traced"],
        "turning": res.settings["refraction"]["turning_direct"],
    }


# --------------------------------------------------------------------------- figures

def fig_offsets(results, path):
    fig, axes = plt.subplots(1, len(results), figsize=(3.1 * len(results), 3.6), sharey=True)
    x = np.arange(1, 5)
    marks = {"harmonic mean": ("o", "C0"), "near-bottom": ("s", "C1"), "1500 m/s": ("^", "C2")}
    for ax, (site, rows) in zip(np.atleast_1d(axes), results.items(), strict=True):
        for k, (name, row) in enumerate(rows.items()):
            m, col = marks[name]
            ax.errorbar(x + 0.12 * (k - 1), row["straight"].mean(0), yerr=row["straight"].std(0),
                        fmt=m, color=col, ms=5, capsize=2,
                        label=f"straight, {name} ({row['c']:.1f})")
        ref = np.concatenate([r["refracted"] for r in rows.values()])
        ax.plot(x, ref.mean(0), "x", color="0.35", ms=7, label="refracted fit (all speeds)")
        ax.plot(x, TABLE2, "*", color="k", ms=11, label="Table II")
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_title(site, fontsize=9)
        ax.set_xticks(x)
        ax.set_xlabel("beacon")
        ax.legend(fontsize=5.5, loc="upper left")
    np.atleast_1d(axes)[0].set_ylabel("plane height - beacon depth (m)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def fig_scan(scans, speeds, path):
    fig, axes = plt.subplots(1, len(scans), figsize=(3.1 * len(scans), 3.4), sharey=True)
    for ax, (site, (off, sdp, marks)) in zip(np.atleast_1d(axes), scans.items(), strict=True):
        for j, b in enumerate(BEACONS):
            ax.plot(speeds, off[:, j], color=f"C{j}", label=f"beacon {b}")
            ax.axhline(TABLE2[j], color=f"C{j}", ls=":", lw=1)
        for name, c in marks.items():
            ax.axvline(c, color="0.5", lw=0.7, ls="--")
            ax.text(c, 0.98, name, rotation=90, fontsize=6, va="top", ha="right",
                    transform=ax.get_xaxis_transform())
        ax.set_title(site, fontsize=9)
        ax.set_xlabel("nominal sound speed (m/s)")
        ax.set_ylim(-30.0, 45.0)
    np.atleast_1d(axes)[0].set_ylabel("straight-ray plane height - depth (m)")
    np.atleast_1d(axes)[0].legend(fontsize=6, title="dotted: Table II", title_fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _leg_x(prof, z_from, z, p):
    """Horizontal run from depth ``z_from`` to each depth ``z`` of the ray with parameter p."""
    x, _ = shoot(prof, np.full_like(z, z_from), z, np.full_like(z, p))
    return x


def fig_rays(profiles, kairei, c_nom, path):
    fig, axes = plt.subplots(1, 4, figsize=(13.5, 3.9))
    ax = axes[0]
    for site, prof in profiles.items():
        z = np.linspace(0.0, 3000.0, 301)
        ax.plot(prof.speed(z), z, label=site)
    ax.axhspan(DEPTHS.min(), DEPTHS.max(), color="0.85", label="beacon depths")
    ax.invert_yaxis()
    ax.set_xlabel("sound speed (m/s)")
    ax.set_ylabel("depth (m)")
    ax.set_title("(a) WOA09 annual profiles", fontsize=9)
    ax.legend(fontsize=6)

    # a surface bounce of beacon 4 (2472 m) from the vehicle 3 km away at 2400 m
    zb, zv, h = 2472.0, 2400.0, 3000.0
    ray = surface_bounce_ray(kairei, zv, zb, h, 0.0)
    p = float(ray.p)
    z1, z2 = np.linspace(0.0, zv, 400), np.linspace(0.0, zb, 400)
    x1 = _leg_x(kairei, zv, z1, p)
    xr = float(_leg_x(kairei, zv, np.array([0.0]), p)[0])
    x2 = xr + _leg_x(kairei, 0.0, z2, p)
    xs = h * zv / (zv + zb)  # straight-ray reflection point (image method)
    ax = axes[1]
    ax.plot(x1, z1, "C0", label="refracted (Kairei)")
    ax.plot(x2, z2, "C0")
    ax.plot([0, xs, h], [zv, 0, zb], "k--", lw=0.8, label="straight")
    ax.plot(0, zv, "ko", ms=4)
    ax.plot(h, zb, "k^", ms=6)
    ax.invert_yaxis()
    ax.set_xlabel("horizontal distance from the vehicle (m)")
    ax.set_title("(b) surface bounce, vehicle to beacon 4", fontsize=9)
    ax.legend(fontsize=6, loc="lower center")
    L = float(np.hypot(h, zv + zb))
    ax.text(0.02, 0.97, f"c_nom T - L = {c_nom * float(ray.time) - L:+.2f} m\n"
            f"(c_nom = {c_nom:.1f} m/s)", transform=ax.transAxes, fontsize=6.5, va="top")

    ax = axes[2]
    ax.plot(x1 - xs * (zv - z1) / zv, z1, "C0", label="up-going leg")
    ax.plot(x2 - (xs + (h - xs) * z2 / zb), z2, "C3", label="down-going leg")
    ax.axvline(0.0, color="0.6", lw=0.8)
    ax.invert_yaxis()
    ax.set_xlabel("refracted - straight, horizontal (m)")
    ax.set_title("(c) where the bounce ray runs", fontsize=9)
    ax.legend(fontsize=6)

    ax = axes[3]
    zv2 = 2465.0
    for k, hh in enumerate((1000.0, 2000.0, 3000.0, 4000.0)):
        rays = direct_times(kairei, zv2, zb, hh)
        pp = float(rays.p)
        zt = float(rays.turning_depth)
        if np.isfinite(zt):  # two legs meeting at the turning depth
            za = np.linspace(zv2, zt, 200)[:-1]
            zc = np.linspace(zt, zb, 200)[1:]
            xa = _leg_x(kairei, zv2, za, pp)
            xc = hh - _leg_x(kairei, zb, zc, pp)
            x, z = np.concatenate([xa, xc]), np.concatenate([za, zc])
        else:
            z = np.linspace(zv2, zb, 200)
            x = _leg_x(kairei, zv2, z, pp)
        ax.plot(x, z - (zv2 + (zb - zv2) * x / hh), color=f"C{k}",
                label=f"h = {hh / 1000:.0f} km" + (f", turns {zt - zb:.1f} m below the beacon"
                                                   if np.isfinite(zt) and zt > zb else ""))
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.invert_yaxis()
    ax.set_xlabel("horizontal distance from the vehicle (m)")
    ax.set_ylabel("depth below the straight chord (m)")
    ax.set_title(f"(d) direct rays, {zv2:.0f} m to {zb:.0f} m", fontsize=9)
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


# --------------------------------------------------------------------------- report

def _pm(a):
    return f"{a.mean():+.1f} ± {a.std():.1f}"


def main(argv=None):
    """Command-line entry point."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--out", default=str(ROOT / "docs" / "refraction.md"))
    args = p.parse_args(argv)
    seeds = range(2) if args.quick else range(5)
    scan_seeds = range(1) if args.quick else range(2)
    speeds = np.arange(1480.0, 1513.0, 4.0 if args.quick else 1.0)
    t_start = time.perf_counter()

    profiles = {s: SoundSpeedProfile.from_woa09(la, lo, directory=WOA09)
                for s, la, lo, _ in SITES}
    results = {s: run_site(profiles[s], seeds) for s in profiles}
    scans = {}
    for s, prof in profiles.items():
        off, sdp = scan_speeds(prof, speeds, scan_seeds)
        scans[s] = (off, sdp, {("hm" if k == "harmonic mean" else k.split()[0]): c
                               for k, c in nominal_speeds(prof).items()})
    kairei = profiles["Kairei"]
    c_k = nominal_speeds(kairei)
    others = other_explanations(seeds, c_k["near-bottom"])
    # the straight-ray fit of straight-ray data, same seeds: what the noise alone does
    base = [fit_survey(bm.simulate_survey("abe58", rng=s), refracted=False) for s in seeds]
    cost = timings(kairei, c_k["harmonic mean"])
    elapsed = time.perf_counter() - t_start

    lines = ["Produced by `python benchmarks/ridge_refraction.py"
             + (" --quick" if args.quick else "") + f"` on {dt.date.today().isoformat()} "
             f"({_report.machine()}; {elapsed:.0f} s). Seeds {list(seeds)} of the `abe58` "
             "preset for every row; each cell is the mean ± sd over the seeds of the "
             "mixture EM's plane height minus the recorded beacon depth (m). Straight: the "
             "default straight-ray fit; refracted: `fit_mixture_em(..., ssp=profile, "
             "sound_speed=c_nom)` with the simulation's own profile and speed. sigma_DP: the "
             "straight fit's direct-path scatter, mean over the seeds, beacons 1-4 (the "
             "simulation's is 3.97 m, the paper's least-squares value).", "",
             "| site (WOA09 cell) | nominal speed (m/s) | straight: beacon 1 | 2 | 3 | 4 "
             "| straight sigma_DP (m) | refracted: 1 | 2 | 3 | 4 | direct rays that turn |",
             "|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|",
             "| Table II (paper) | ? | " + " | ".join(f"{v:+.0f}" for v in TABLE2)
             + " | 3.97 | | | | | |",
             "| no profile (straight rays) | - | "
             + " | ".join(_pm(np.array([f["straight"][j] for f in base])) for j in range(4))
             + " | " + " / ".join(f"{v:.1f}" for v in np.mean([f["sigma_dp"] for f in base], 0))
             + " | | | | | |"]
    for (s, la, lo, _), prof in zip(SITES, profiles.values(), strict=True):
        cell = prof.source.split("cell ")[1].split(")")[0] + ")"
        for name, row in results[s].items():
            lines.append(
                f"| {s} {cell} | {name} {row['c']:.1f} | "
                + " | ".join(_pm(row["straight"][:, j]) for j in range(4))
                + " | " + " / ".join(f"{v:.1f}" for v in row["sigma_dp"].mean(0)) + " | "
                + " | ".join(_pm(row["refracted"][:, j]) for j in range(4))
                + f" | {100 * row['turning']:.0f} % |")
    lines += ["", "Sites: " + "; ".join(
        f"{label} ({la:+.2f}, {lo:+.2f}): {prof.source}"
        for (s, la, lo, label), prof in zip(SITES, profiles.values(), strict=True)) + ".", ""]

    lines += ["Nominal speed scan (straight-ray fit, mean over seeds "
              f"{list(scan_seeds)}, {speeds[0]:.0f}-{speeds[-1]:.0f} m/s in steps of "
              f"{speeds[1] - speeds[0]:.0f} m/s): the speed whose offsets come closest to "
              "Table II (least squares over the four beacons) and the rms misfit there.", "",
              "| site | best nominal speed (m/s) | offsets there: 1 | 2 | 3 | 4 "
              "| rms misfit to Table II (m) | straight sigma_DP there (m) |",
              "|---|---:|---:|---:|---:|---:|---:|---|"]
    for s, (off, sdp, _) in scans.items():
        rms = np.sqrt(np.mean((off - TABLE2) ** 2, axis=1))
        k = int(np.argmin(rms))
        lines.append(f"| {s} | {speeds[k]:.0f} | " + " | ".join(f"{v:+.1f}" for v in off[k])
                     + f" | {rms[k]:.1f} | " + " / ".join(f"{v:.1f}" for v in sdp[k]) + " |")
    best_uniform = np.sqrt(np.mean((TABLE2 - TABLE2.mean()) ** 2))
    lines += ["", f"For comparison: the same offset on every beacon cannot come closer to "
              f"Table II than {best_uniform:.1f} m rms (at +{TABLE2.mean():.0f} m).", ""]

    lines += ["Other candidate explanations, without refraction (straight-ray fit, seeds "
              f"{list(seeds)}):", "",
              "| simulated | beacon 1 | 2 | 3 | 4 | straight sigma_DP (m) |",
              "|---|---:|---:|---:|---:|---|"]
    for label, fits in others:
        off = np.array([f["straight"] for f in fits])
        lines.append(f"| {label} | " + " | ".join(_pm(off[:, j]) for j in range(4)) + " | "
                     + " / ".join(f"{v:.1f}" for v in np.mean([f["sigma_dp"] for f in fits], 0))
                     + " |")
    lines += ["", "Cost (best of 5, this machine): simulating the `abe58` survey "
              f"{1000 * cost['sim_straight']:.0f} ms with straight rays, "
              f"{1000 * cost['sim_refracted']:.0f} ms refracted through the Kairei profile; "
              f"fitting beacon 4 ({cost['n']} ranges, {cost['turning']} turning direct rays) "
              f"{1000 * cost['fit_straight']:.0f} ms straight, "
              f"{1000 * cost['fit_refracted']:.0f} ms refracted ({cost['planes']} planes "
              "traced for the bounce table)."]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        figdir = Path(args.out).parent / "figures"
        figdir.mkdir(exist_ok=True)
        fig_offsets(results, figdir / "refraction_offsets.png")
        fig_scan({s: v for s, v in scans.items()}, speeds, figdir / "refraction_speed_scan.png")
        fig_rays(profiles, kairei, c_k["harmonic mean"], figdir / "refraction_rays.png")
        _report.write_section(args.out, "ridge_refraction", text)
        print(f"wrote {args.out} and {figdir}/refraction_*.png")


if __name__ == "__main__":
    main()
