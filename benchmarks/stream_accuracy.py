"""The online navigator against the batch one on simulated dives (issue 13's acceptance).

Run from the repository root::

    python benchmarks/stream_accuracy.py            # 10 dives per preset; writes the docs
    python benchmarks/stream_accuracy.py --seeds 2  # prints only
    python benchmarks/stream_accuracy.py --seeds 4 --alpha 0.8   # another step size, prints only
    python benchmarks/stream_accuracy.py --option warmup=400   # a Navigator option, prints only

Dives are ``simulate_dive(preset, rng=seed)`` (``bayes_mpem.lbl.navigate``),
``abe58`` and ``random`` geometries, with navigate's dead reckoning (heading
bias in [-2, 2] deg, speed scale in [0.98, 1.02], random walk 0.1 m/sqrt(s),
first fix 10 m off). Each dive's pings are fed in time order to a
:class:`~bayes_mpem.lbl.navigate.online.Navigator` with its defaults (warm-up 200
replies, ``alpha = 1``), and compared with :func:`~bayes_mpem.lbl.navigate.navigate`
(the batch ECM and smoother, defaults, ``rng=0``):

* **plane heights after 500 replies per beacon**: the online ``d0`` of every
  beacon at the first epoch when each has 500 replies, against ``navigate`` on
  the same pings (those up to that epoch); largest difference over the beacons;
* **labels**: the online label of every reply after the warm-up (given as the
  reply arrived) against ``navigate``'s on the whole dive;
* **track**: the filtered position after each epoch's last line, after the
  warm-up, against the truth; its RMSE over the batch smoother's on the same
  epochs (and the 95 % ellipse coverage of both);
* **the floor of that ratio**: the exact Kalman filter and RTS smoother of the
  same dive with everything known but the dead reckoning's random walk
  (:func:`ideal_errors`), on the same epochs: what no causal estimator can beat.
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
from bayes_mpem.lbl.navigate.online import Navigator

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


def ideal_errors(sim, q: float = 0.1, start_sd: float = 10.0):
    """Errors of the ideal Kalman filter and RTS smoother of a dive (the floor of their ratio).

    Everything but the dead reckoning's random walk known: the true classes
    (outliers left out), reflectors, scales, heading bias and speed scale. The
    state is the walk ``x_k = p_k - p_{k-1} - s R(beta) Delta_k`` summed (0 at the
    first fix, prior sd ``start_sd``); a reply of class c at epoch k measures
    ``y = g^T x_k + e`` exactly (``g`` the range's gradient at the true position,
    ``e`` its realised noise, ``z - f_c(p_true)``), so the filter and smoother
    are the exact linear ones, and their errors are those of the best causal
    and the best non-causal estimate of the track given the same data.

    Returns
    -------
    times, e_filter, e_smoother : numpy.ndarray
        ``(K,)`` epoch times, ``(K, 2)`` errors.
    """
    from bayes_mpem.lbl.navigate.model import predict_ranges, rotation

    tt = sim.true_track
    times = tt["time"].to_numpy()
    p = tt[["x", "y"]].to_numpy()
    dr = tt[["dr_x", "dr_y"]].to_numpy()
    nav = sim.truth["navigation"]
    R, _ = rotation(np.deg2rad(nav["heading_bias_deg"]))
    w = np.diff(p, axis=0) - nav["speed_scale"] * np.diff(dr, axis=0) @ R.T
    x_true = np.vstack([np.zeros(2), np.cumsum(w, axis=0)])
    s = sim.survey
    lab = np.asarray(sim.labels)
    k_of = np.searchsorted(times, np.asarray(s.time))
    use = np.isin(lab, ("dp", "mp"))
    g = np.zeros((lab.size, 2))
    e = np.zeros(lab.size)
    var = np.ones(lab.size)
    for bid, tr in sim.simulation.truth.items():
        m = use & (np.asarray(s.beacon) == bid)
        b = s.beacons.loc[bid]
        k = k_of[m]
        pr = predict_ranges(p[k, 0], p[k, 1], np.asarray(s.depth)[m], (b.x, b.y, b.depth),
                            tr["d0"], tr["path"])
        mp = lab[m] == "mp"
        g[m] = np.where(mp[:, None], pr.grad_multipath, pr.grad_direct)
        e[m] = np.asarray(s.range)[m] - np.where(mp, pr.multipath, pr.direct)
        var[m] = np.where(mp, tr["sigma_mp"], tr["sigma_dp"]) ** 2
    rows = np.flatnonzero(use)
    order = rows[np.argsort(k_of[rows], kind="stable")]
    bounds = np.searchsorted(k_of[order], np.arange(times.size + 1))
    n = times.size
    xf, pf, pp = np.zeros((n, 2)), np.zeros((n, 2, 2)), np.zeros((n, 2, 2))
    x, P = np.zeros(2), np.eye(2) * start_sd ** 2
    for k in range(n):
        if k:
            P = P + np.eye(2) * q ** 2 * (times[k] - times[k - 1])
        pp[k] = P
        for i in order[bounds[k]:bounds[k + 1]]:
            h = g[i]
            y = h @ x_true[k] + e[i]
            ph = P @ h
            gain = ph / (h @ ph + var[i])
            x = x + gain * (y - h @ x)
            P = P - np.outer(gain, ph)
        xf[k], pf[k] = x, P
    xs = xf.copy()
    for k in range(n - 2, -1, -1):
        c = pf[k] @ np.linalg.inv(pp[k + 1])
        xs[k] = xf[k] + c @ (xs[k + 1] - xf[k])
    return times, xf - x_true, xs - x_true


def evaluate(preset: str, seed: int, alpha: float = 1.0, options=None) -> dict:
    sim = simulate_dive(preset, rng=seed)
    table = sim.survey.table
    beacons = sim.survey.beacons.reset_index()
    cut = cut_at(table, 500)
    nav = Navigator(beacons, alpha=alpha, rng=0, **(options or {}))
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
    ti, ef, es = ideal_errors(sim)
    ki = np.searchsorted(ti, t[sel])
    rmse_f = float(np.sqrt(np.mean(np.sum(ef[ki] ** 2, 1))))
    rmse_s = float(np.sqrt(np.mean(np.sum(es[ki] ** 2, 1))))
    return {"preset": preset, "seed": seed, "pings": len(table), "cut": cut,
            "d0_vs_batch": max(dd), "d0_vs_truth": max(truth_d0),
            "labels_vs_batch": float(np.mean(labels[after] == batch_labels[after])),
            "labels_vs_truth": float(np.mean(labels[after] == sim.labels[after])),
            "batch_labels_vs_truth": float(np.mean(batch_labels[after] == sim.labels[after])),
            "rmse_online": rmse_on, "rmse_batch": rmse_b, "ratio": rmse_on / rmse_b,
            "rmse_ideal_filter": rmse_f, "rmse_ideal_smoother": rmse_s,
            "ideal_ratio": rmse_f / rmse_s, "online_vs_ideal": rmse_on / rmse_f,
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
           f"{ok('ratio', lambda s: s <= 1.5)} / {n} |",
           f"| (the floor) the ideal filter's RMSE over the ideal smoother's, same epochs | "
           f"RMSE ideal filter / ideal smoother | {df.ideal_ratio.median():.2f} | "
           f"{df.ideal_ratio.max():.2f} | {ok('ideal_ratio', lambda s: s <= 1.5)} / {n} |",
           f"| (the filter's own loss) online RMSE over the ideal filter's | RMSE online / ideal "
           f"filter | {df.online_vs_ideal.median():.2f} | {df.online_vs_ideal.max():.2f} | - |",
           "",
           "| dive | pings | d0 vs batch (m) | d0 vs truth (m) | labels vs batch | labels vs "
           "truth (online / batch) | RMSE online / batch (m) | ratio | ideal filter / smoother "
           "(m) | ideal ratio | 95 % coverage online / batch | paths warm-up -> end | "
           "s online / batch |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(
            f"| {r['preset']} {r['seed']} | {r['pings']} | {r['d0_vs_batch']:.2f} | "
            f"{r['d0_vs_truth']:.2f} | {r['labels_vs_batch']:.4f} | {r['labels_vs_truth']:.4f}"
            f" / {r['batch_labels_vs_truth']:.4f} | {r['rmse_online']:.2f} / "
            f"{r['rmse_batch']:.2f} | {r['ratio']:.2f} | {r['rmse_ideal_filter']:.2f} / "
            f"{r['rmse_ideal_smoother']:.2f} | {r['ideal_ratio']:.2f} | "
            f"{r['coverage_online']:.3f} / "
            f"{r['coverage_batch']:.3f} | {r['warmup_paths']} -> {r['paths']} | "
            f"{r['sec_online']:.2f} / {r['sec_batch']:.2f} |")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10, help="dives per preset (default 10)")
    ap.add_argument("--alpha", type=float, default=1.0, help="online-EM step-size exponent")
    ap.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                    help="a Navigator option (a number), e.g. warmup=400 (repeatable)")
    args = ap.parse_args(argv)
    options = {}
    for item in args.option:
        name, _, value = item.partition("=")
        options[name] = int(value) if value.isdigit() else float(value)
    rows = []
    for preset in PRESETS:
        for seed in range(args.seeds):
            r = evaluate(preset, seed, args.alpha, options)
            rows.append(r)
            print(f"{preset} {seed}: d0 {r['d0_vs_batch']:.2f} m, labels "
                  f"{r['labels_vs_batch']:.4f}, ratio {r['ratio']:.2f} (ideal "
                  f"{r['ideal_ratio']:.2f}), coverage "
                  f"{r['coverage_online']:.3f}", flush=True)
    text = report(rows)
    print(text)
    if args.seeds >= 10 and args.alpha == 1.0 and not options:
        write_section(ROOT / "docs" / "benchmarks.md", "stream_accuracy",
                      "## Streaming: the online navigator against the batch one "
                      "(`benchmarks/stream_accuracy.py`)\n\n" + text)
        write_section(ROOT / "docs" / "stream.md", "stream_accuracy", text)


if __name__ == "__main__":
    main()
