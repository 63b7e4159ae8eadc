"""The online navigator against the batch one on simulated dives (issue 13's acceptance).

Run from the repository root::

    python benchmarks/stream_accuracy.py            # 10 dives per preset; writes the docs
    python benchmarks/stream_accuracy.py --seeds 2  # prints only
    python benchmarks/stream_accuracy.py --seeds 4 --alpha 0.8   # another step size, prints only

Dives are ``simulate_dive(preset, rng=seed)`` (``bayes_mpem.lbl.navigate``),
``abe58`` and ``random`` geometries, with navigate's dead reckoning (heading
bias in [-2, 2] deg, speed scale in [0.98, 1.02], random walk 0.1 m/sqrt(s),
first fix 10 m off). Each dive's pings are fed in time order to a
:class:`~bayes_mpem.lbl.online.Navigator` with its defaults (warm-up 200
replies, ``alpha = 1``), and compared with :func:`~bayes_mpem.lbl.navigate.navigate`
(the batch ECM and smoother, defaults, ``rng=0``):

* **plane heights after 500 replies per beacon**: the online ``d0`` of every
  beacon at the first epoch when each has 500 replies, against ``navigate`` on
  the same pings (those up to that epoch); largest difference over the beacons;
* **labels**: the online label of every reply after the warm-up (given as the
  reply arrived) against ``navigate``'s on the whole dive;
* **track**: the filtered position after each epoch's last line, after the
  warm-up, against the truth; its RMSE over the batch smoother's on the same
  epochs (and the 95 % ellipse coverage of both).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from bayes_mpem.lbl.navigate import navigate, simulate_dive
from bayes_mpem.lbl.online import Navigator

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ("abe58", "random")
CHI2_95 = 5.991


def cut_at(table: pd.DataFrame, n: int) -> int:
    """Rows up to the end of the first epoch at which every beacon has ``n`` replies."""
    reply = table["range"].notna().to_numpy()
    beacon = table["beacon"].to_numpy()
    first = 0
    for b in np.unique(beacon):
        mine = np.flatnonzero(reply & (beacon == b))
        if mine.size < n:
            return len(table)
        first = max(first, int(mine[n - 1]))
    return int(np.searchsorted(table["time"].to_numpy(), table["time"].iloc[first], "right"))


def _coverage(err, cov):
    det = cov[:, 0, 0] * cov[:, 1, 1] - cov[:, 0, 1] ** 2
    m2 = (cov[:, 1, 1] * err[:, 0] ** 2 - 2 * cov[:, 0, 1] * err[:, 0] * err[:, 1]
          + cov[:, 0, 0] * err[:, 1] ** 2) / det
    return float(np.mean(m2 < CHI2_95))


def evaluate(preset: str, seed: int, alpha: float = 1.0) -> dict:
    sim = simulate_dive(preset, rng=seed)
    table = sim.survey.table
    beacons = sim.survey.beacons.reset_index()
    cut = cut_at(table, 500)
    nav = Navigator(beacons, alpha=alpha, rng=0)
    t0 = time.perf_counter()
    head = nav.run(table.iloc[:cut])
    online_d0 = {b: v["d0"] for b, v in nav.reflectors().items()}
    out = pd.concat([head, nav.run(table.iloc[cut:])], ignore_index=True)
    sec_online = time.perf_counter() - t0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prefix = navigate(table.iloc[:cut], beacons, rng=0)
        t0 = time.perf_counter()
        whole = navigate(sim.survey, rng=0)
        sec_batch = time.perf_counter() - t0
    dd = [abs(online_d0[b] - prefix.state.d0[j]) for j, b in enumerate(prefix.dive.beacon_ids)
          if prefix.beacons[b]["mp"]]
    truth_d0 = [abs(online_d0[b] - sim.simulation.truth[b]["d0"]) for b in online_d0]
    reply = table["range"].notna().to_numpy()
    after = (out["phase"] == "online").to_numpy() & reply
    labels = out["label"].to_numpy()
    batch_labels = whole.classified()["label"].to_numpy()
    t = out["time"].to_numpy()
    sel = np.r_[t[1:] != t[:-1], True] & (out["phase"] == "online").to_numpy()
    truth = sim.true_track.set_index("time").loc[t[sel], ["x", "y"]].to_numpy()
    e_on = out.loc[sel, ["x", "y"]].to_numpy() - truth
    cov_on = np.stack([out.loc[sel, "sd_x"] ** 2, out.loc[sel, "cov_xy"], out.loc[sel, "cov_xy"],
                       out.loc[sel, "sd_y"] ** 2], axis=1).reshape(-1, 2, 2)
    k = np.searchsorted(whole.dive.times, t[sel])
    e_b = whole.track[k] - truth
    rmse_on = float(np.sqrt(np.mean(np.sum(e_on ** 2, 1))))
    rmse_b = float(np.sqrt(np.mean(np.sum(e_b ** 2, 1))))
    return {"preset": preset, "seed": seed, "pings": len(table), "cut": cut,
            "d0_vs_batch": max(dd), "d0_vs_truth": max(truth_d0),
            "labels_vs_batch": float(np.mean(labels[after] == batch_labels[after])),
            "labels_vs_truth": float(np.mean(labels[after] == sim.labels[after])),
            "batch_labels_vs_truth": float(np.mean(batch_labels[after] == sim.labels[after])),
            "rmse_online": rmse_on, "rmse_batch": rmse_b, "ratio": rmse_on / rmse_b,
            "coverage_online": _coverage(e_on, cov_on),
            "coverage_batch": _coverage(e_b, whole.cov[k]),
            "paths": "".join("d" if m["path"] == "double" else "t"
                             for m in nav.reflectors().values()),
            "warmup_paths": "".join("d" if m["path"] == "double" else "t"
                                    for m in nav.warmup_record["beacons"].values()),
            "sec_online": sec_online, "sec_batch": sec_batch}


def report(rows) -> str:
    df = pd.DataFrame(rows)
    n = len(df)
    ok = lambda col, cond: int(cond(df[col]).sum())  # noqa: E731
    out = [f"*{dt.date.today().isoformat()}, {machine()}; {n} dives "
           f"({', '.join(f'{(df.preset == p).sum()} {p}' for p in PRESETS)}).*", "",
           "| acceptance | measure | median | worst | dives meeting it |", "|---|---|---|---|---|",
           "| plane heights within 3 m of the batch EM's after 500 replies per beacon | largest "
           "difference online - batch in d0 over the beacons (m) | "
           f"{df.d0_vs_batch.median():.2f} | "
           f"{df.d0_vs_batch.max():.2f} | {ok('d0_vs_batch', lambda s: s < 3)} / {n} |",
           f"| labels agree with the batch labels on >= 98 % of replies after the warm-up | "
           f"agreement | {df.labels_vs_batch.median():.4f} | {df.labels_vs_batch.min():.4f} | "
           f"{ok('labels_vs_batch', lambda s: s >= 0.98)} / {n} |",
           f"| filtered track RMSE within 1.5x the batch smoother's | RMSE online / batch | "
           f"{df.ratio.median():.2f} | {df.ratio.max():.2f} | "
           f"{ok('ratio', lambda s: s <= 1.5)} / {n} |", "",
           "| dive | pings | d0 vs batch (m) | d0 vs truth (m) | labels vs batch | labels vs "
           "truth (online / batch) | RMSE online / batch (m) | ratio | 95 % coverage online / "
           "batch | paths warm-up -> end | s online / batch |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(
            f"| {r['preset']} {r['seed']} | {r['pings']} | {r['d0_vs_batch']:.2f} | "
            f"{r['d0_vs_truth']:.2f} | {r['labels_vs_batch']:.4f} | {r['labels_vs_truth']:.4f}"
            f" / {r['batch_labels_vs_truth']:.4f} | {r['rmse_online']:.2f} / "
            f"{r['rmse_batch']:.2f} | {r['ratio']:.2f} | {r['coverage_online']:.3f} / "
            f"{r['coverage_batch']:.3f} | {r['warmup_paths']} -> {r['paths']} | "
            f"{r['sec_online']:.2f} / {r['sec_batch']:.2f} |")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10, help="dives per preset (default 10)")
    ap.add_argument("--alpha", type=float, default=1.0, help="online-EM step-size exponent")
    args = ap.parse_args(argv)
    rows = []
    for preset in PRESETS:
        for seed in range(args.seeds):
            r = evaluate(preset, seed, args.alpha)
            rows.append(r)
            print(f"{preset} {seed}: d0 {r['d0_vs_batch']:.2f} m, labels "
                  f"{r['labels_vs_batch']:.4f}, ratio {r['ratio']:.2f}, coverage "
                  f"{r['coverage_online']:.3f}", flush=True)
    text = report(rows)
    print(text)
    if args.seeds >= 10 and args.alpha == 1.0:
        write_section(ROOT / "docs" / "benchmarks.md", "stream_accuracy",
                      "## Streaming: the online navigator against the batch one "
                      "(`benchmarks/stream_accuracy.py`)\n\n" + text)
        write_section(ROOT / "docs" / "stream.md", "stream_accuracy", text)


if __name__ == "__main__":
    main()
