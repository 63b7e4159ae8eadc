"""Recovery of a known truth by the mixture EM over many simulated surveys.

Run from the repository root::

    python benchmarks/recovery.py             # writes docs/recovery.md
    python benchmarks/recovery.py --quick     # fewer surveys, prints only

For every survey (the ``abe58`` preset and the ``random`` preset: 3-5
beacons, water 800-4500 m deep, vehicle from near the bottom to mid-water,
random weights and noise) it fits every beacon and records the errors the
foundation issue sets limits on: d0 within 3 m, sigma_MP within 25 %, each
weight within 0.05, at least 97 % of ranges labelled correctly.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path

import numpy as np

import bayes_mpem as bm

ROOT = Path(__file__).resolve().parents[1]
CLASSES = ("dp", "mp", "ol")


def one_survey(preset, seed, path="triangle"):
    """Fit one simulated survey; return its worst errors."""
    sim = bm.simulate_survey(preset, rng=seed, path=path)
    res = bm.fit(sim.survey, path=path, rng=seed)
    lab = res.classified()["label"].to_numpy()
    replied = sim.labels != "no_reply"
    d0 = max(abs(r.d0 - sim.truth[b]["d0"]) for b, r in res.results.items())
    sig = max(abs(r.sigma_mp / sim.truth[b]["sigma_mp"] - 1) for b, r in res.results.items())
    w = max(abs(r.weights[c] - sim.truth[b]["weights"][c])
            for b, r in res.results.items() for c in CLASSES)
    acc = float(np.mean(lab[replied] == sim.labels[replied]))
    z = [(r.d0 - sim.truth[b]["d0"]) / r.d0_se for b, r in res.results.items()]
    ok = d0 < 3 and sig < 0.25 and w < 0.05 and acc >= 0.97
    return {"preset": preset, "path": path, "seed": seed, "beacons": len(res.results),
            "d0": d0, "sigma": sig, "w": w, "acc": acc, "ok": ok, "z": z}


def main(argv=None):
    """Command-line entry point."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--out", default=str(ROOT / "docs" / "recovery.md"))
    args = p.parse_args(argv)
    n_abe, n_rand, n_dbl = (3, 10, 2) if args.quick else (20, 100, 10)
    runs = [one_survey("abe58", s) for s in range(n_abe)]
    runs += [one_survey("random", 1000 + s) for s in range(n_rand)]
    runs += [one_survey("abe58", s, "double") for s in range(n_dbl)]
    groups = {}
    for r in runs:
        groups.setdefault((r["preset"], r["path"]), []).append(r)
    lines = ["# Recovery of a known truth (mixture EM)", "",
             "Produced by `python benchmarks/recovery.py" + (" " + " ".join(sys.argv[1:])
                                                            if argv is None and sys.argv[1:]
                                                            else "") + "` on "
             f"{dt.date.today().isoformat()}. Each row: the worst error over every beacon of "
             "every survey in the group (limits: d0 < 3 m, sigma_MP < 25 %, weights < 0.05, "
             "labels >= 97 %).", "",
             "| surveys | path | count | beacons | worst d0 error (m) | median d0 error (m) "
             "| worst sigma_MP error | worst weight error | lowest label accuracy "
             "| median label accuracy | surveys within all limits | sd of d0 error / d0_se "
             "| within +-1.96 d0_se |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for (preset, path), rs in groups.items():
        arr = {k: np.array([r[k] for r in rs]) for k in ("d0", "sigma", "w", "acc")}
        z = np.concatenate([r["z"] for r in rs])
        lines.append(
            f"| {preset} | {path} | {len(rs)} | {sum(r['beacons'] for r in rs)} "
            f"| {arr['d0'].max():.2f} | {np.median(arr['d0']):.2f} "
            f"| {100 * arr['sigma'].max():.1f} % | {arr['w'].max():.3f} "
            f"| {100 * arr['acc'].min():.2f} % | {100 * np.median(arr['acc']):.2f} % "
            f"| {sum(r['ok'] for r in rs)} / {len(rs)} | {np.std(z):.2f} "
            f"| {100 * np.mean(np.abs(z) < 1.96):.1f} % |")
    bad = [r for r in runs if not r["ok"]]
    lines += ["", "Surveys outside a limit: " + (", ".join(
        f"{r['preset']} seed {r['seed']} (d0 {r['d0']:.2f} m, sigma {100 * r['sigma']:.0f} %, "
        f"w {r['w']:.3f}, labels {100 * r['acc']:.2f} %, largest |d0 error| / d0_se "
        f"{max(np.abs(r['z'])):.2f})" for r in bad) or "none") + ".", "",
        "`d0_se` is the approximate standard error the mixture EM reports. Where the sd of the "
        "normalised error is ~1 and ~95 % fall within +-1.96 d0_se, the fit is unbiased and "
        "its misses of the 3 m limit are sampling noise of small, noisy beacons, not failures "
        "of the method.", ""]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        Path(args.out).write_text(text)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
