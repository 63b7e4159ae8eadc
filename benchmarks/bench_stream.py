"""Latency and memory of the online navigator over a long replay (issue 13's acceptance).

Run from the repository root (under ``nice`` on a shared machine)::

    python benchmarks/bench_stream.py                  # 1,000,000 pings; writes docs/benchmarks.md
    python benchmarks/bench_stream.py --pings 100000   # prints only

The dive is ``simulate_dive("abe58", rng=0, n_cycles=N / 4)``: four beacons
interrogated every 12 s, the preset's lawnmower (stretched over the dive, so
the vehicle moves slowly), dead reckoning with heading bias, speed scale and
random walk. The pings are fed one by one to :class:`Navigator.update`, as
``Ping`` tuples built from the arrays (so the time is the navigator's, not
pandas'); each call is timed with ``time.perf_counter_ns`` into a preallocated
array, and nothing is kept of the answers. Reported per block of pings:
p50, p99, p99.9 and the largest latency, the resident set size (``/proc/self/statm``)
at the end of the block, and the navigator's allocated memory (``tracemalloc``
is not used: it would slow every call; the state's JSON size is reported
instead, a bound on what the navigator holds). The warm-up's batch fit, one
call, is reported apart.

Part 2: the cost of one line through the whole command (``LineParser.parse`` +
``update`` + ``json.dumps``) over the first 100,000 CSV lines; part 3: the
per-ping model evaluated with NumPy (``lbl.navigate.model``) against the plain
floats of ``lbl.online.kernel``, the reason the kernel exists.

The 1-minute load average (``os.getloadavg``) is recorded before and after:
the machine may be shared, and latencies measured under load are inflated.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import sys
import time
import timeit
import warnings
from pathlib import Path

import numpy as np

from bayes_mpem.io.lines import LineParser, Ping
from bayes_mpem.lbl.navigate import model, simulate_dive
from bayes_mpem.lbl.navigate.online import Navigator, kernel

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def rss_mb() -> float:
    """Resident set size of this process (MB)."""
    pages = int(Path("/proc/self/statm").read_text().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def replay(n_pings: int, blocks: int):
    sim = simulate_dive("abe58", rng=0, n_cycles=max(n_pings // 4, 60))
    s = sim.survey
    t, b, z = np.asarray(s.time, float), s.beacon, np.asarray(s.range, float)
    x, y, d = np.asarray(s.x, float), np.asarray(s.y, float), np.asarray(s.depth, float)
    n = min(n_pings, t.size)
    nav = Navigator(s.beacons.reset_index(), rng=0)
    lat = np.zeros(n, np.int64)
    edges = np.linspace(0, n, blocks + 1).astype(int)
    rows, warm = [], None
    clock = time.perf_counter_ns
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(blocks):
            for i in range(edges[k], edges[k + 1]):
                zi = z[i]
                ping = Ping(t[i], b[i], None if zi != zi else zi, x[i], y[i], d[i])
                c0 = clock()
                nav.update(ping)
                lat[i] = clock() - c0
                if warm is None and nav.phase == "online":
                    warm = (i, lat[i] / 1e9)
            block = lat[edges[k]:edges[k + 1]].copy()
            if warm is not None and edges[k] <= warm[0] < edges[k + 1]:
                block = np.delete(block, warm[0] - edges[k])
            p = np.percentile(block, [50, 99, 99.9]) / 1e3
            rows.append({"first": int(edges[k]) + 1, "last": int(edges[k + 1]), "p50": p[0],
                         "p99": p[1], "p999": p[2], "max": block.max() / 1e3, "rss": rss_mb(),
                         "state_bytes": len(json.dumps(nav.to_dict()))})
            r = rows[-1]
            print(f"pings {r['first']:>8}-{r['last']:>8}: p50 {r['p50']:.1f} us, p99 "
                  f"{r['p99']:.1f} us, p99.9 {r['p999']:.1f} us, max {r['max']:.0f} us, RSS "
                  f"{r['rss']:.1f} MB, state {r['state_bytes']} B", flush=True)
    return rows, warm, n, sim


def whole_line(sim, n_lines: int):
    """Seconds per line of parse + update + json.dumps over CSV lines."""
    tab = sim.survey.table
    cols = ["time", "beacon", "range", "x", "y", "depth"]
    text = tab[cols].iloc[:n_lines].to_csv(index=False, header=False).splitlines()
    parser = LineParser(sim.survey.beacon_ids)
    parser.parse(",".join(cols), 1)
    nav = Navigator(sim.survey.beacons.reset_index(), rng=0)
    lat = np.zeros(len(text), np.int64)
    clock = time.perf_counter_ns
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, line in enumerate(text):
            c0 = clock()
            _, ping = parser.parse(line, i + 2)
            json.dumps({"line": i + 2, **nav.update(ping).to_dict()}, allow_nan=False,
                       separators=(",", ":"))
            lat[i] = clock() - c0
    lat = lat[nav.options["warmup"] + 10:]  # after the warm-up
    return np.percentile(lat, [50, 99]) / 1e3


def kernel_against_numpy():
    """Microseconds of the per-ping model with NumPy and with plain floats."""
    lw = np.log([0.5, 0.3, 0.2])
    n = 20000

    def with_numpy():
        p = model.predict_ranges(100.0, 50.0, 2000.0, (0.0, 0.0, 2400.0), 2400.0, "triangle")
        model.class_log_joint(3000.0, p.direct, p.multipath, 3.0, 8.0, -8.0, lw)
        model.dr_step([0.0, 0.0], [10.0, 0.0], 0.01, 1.0)

    def with_floats():
        r = kernel.ranges(100.0, 50.0, 2000.0, 0.0, 0.0, 2400.0, 2400.0, False)
        kernel.class_probabilities(3000.0, r[0], r[1], 3.0, 8.0, -8.0, math.log(0.5),
                                   math.log(0.3), math.log(0.2))
        kernel.dr_step(10.0, 0.0, 0.01, 1.0)

    return (min(timeit.repeat(with_numpy, number=n, repeat=3)) / n * 1e6,
            min(timeit.repeat(with_floats, number=n, repeat=3)) / n * 1e6)


def report(rows, warm, n, line_p, kern, load0, load1) -> str:
    out = [f"*{dt.date.today().isoformat()}, {machine()}; 1-minute load average "
           f"{load0:.2f} before, {load1:.2f} after (a shared machine: latencies measured under "
           "load are inflated; re-run on a quiet machine).*", "",
           f"`Navigator.update` over a replay of {n:,} pings of a simulated `abe58` dive (four "
           "beacons every 12 s), latency per ping in microseconds, per block of the replay "
           "(the warm-up's batch fit excluded: one call, "
           f"{warm[1]:.2f} s at ping {warm[0] + 1}); RSS of the process at the end of each "
           "block; the size of the navigator's saved state.", "",
           "| pings | p50 (us) | p99 (us) | p99.9 (us) | max (us) | RSS (MB) | state (bytes) |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['first']:,}-{r['last']:,} | {r['p50']:.1f} | {r['p99']:.1f} | "
                   f"{r['p999']:.1f} | {r['max']:.0f} | {r['rss']:.1f} | {r['state_bytes']} |")
    out += ["", f"One line through the command's path (parse a CSV line, `update`, "
            f"`json.dumps` the answer), after the warm-up: p50 {line_p[0]:.1f} us, p99 "
            f"{line_p[1]:.1f} us.", "",
            f"The per-ping model (range prediction with derivatives, class probabilities, "
            f"dead-reckoning step) costs {kern[0]:.1f} us with `lbl.navigate.model`'s NumPy "
            f"functions on scalars and {kern[1]:.1f} us with `lbl.online.kernel`'s plain floats "
            "(the tests check that they agree to 1e-12)."]
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pings", type=int, default=1_000_000)
    ap.add_argument("--blocks", type=int, default=10)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    rows, warm, n, sim = replay(args.pings, args.blocks)
    line_p = whole_line(sim, min(100_000, n))
    kern = kernel_against_numpy()
    load1 = os.getloadavg()[0]
    text = report(rows, warm, n, line_p, kern, load0, load1)
    print(text)
    if args.pings >= 1_000_000:
        write_section(ROOT / "docs" / "benchmarks.md", "bench_stream",
                      "## Streaming: latency and memory per ping (`benchmarks/bench_stream.py`)"
                      "\n\n" + text)
        write_section(ROOT / "docs" / "stream.md", "bench_stream", text)


if __name__ == "__main__":
    main()
