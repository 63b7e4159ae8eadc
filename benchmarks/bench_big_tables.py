"""`bayes-mpem fit` on big tables, end to end: CSV and Parquet, 1M and 10M rows, peak memory.

For each size, a simulated abe58 survey (seed 1, ``n_cycles = rows / 4``) is written once
as ``pings.csv`` and ``pings.parquet`` into a cache folder; then ``bayes-mpem fit`` runs
in a fresh process (import, read, validation, both multipath geometries per beacon by
the mixture EM, ``classified`` and ``history.json``, ``summary.json``), with the
classified table written in the input's format. Reported: wall seconds (median of the
repeats, fresh processes interleaved), the process's peak resident memory (``ru_maxrss``),
and the load average before and after, since the machine may be shared. ``--phases``
also times the phases in one process (import, read and validate, EM, write).

    nice -n 10 .venv/bin/python benchmarks/bench_big_tables.py --sizes 1000000 10000000
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CLI = [sys.executable, "-c", "import sys; from bayes_mpem.cli import main; sys.exit(main())"]


def make_data(rows: int, cache: Path) -> Path:
    folder = cache / f"abe58_{rows}"
    if (folder / "pings.parquet").exists():
        return folder
    import pandas as pd

    import bayes_mpem as bm

    sim = bm.simulate_survey("abe58", rng=1, n_cycles=rows // 4)
    sim.write(folder)
    pd.read_csv(folder / "pings.csv", dtype=str, keep_default_na=False).to_parquet(
        folder / "pings.parquet")
    return folder


def run_fit(folder: Path, fmt: str, out: Path) -> tuple[float, float]:
    """Wall seconds and peak resident memory (MB) of one `bayes-mpem fit` process."""
    argv = [*CLI, "fit", str(folder / f"pings.{fmt}"), "--beacons", str(folder / "beacons.csv"),
            "--out", str(out), "--table-format", fmt]
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    if status != 0:
        raise RuntimeError(f"fit failed: {proc.stderr.read().decode()[-2000:]}")
    return seconds, usage.ru_maxrss / 1024.0


def phases(folder: Path, fmt: str, out: Path) -> dict:
    """Seconds of each phase of `fit` in one process (the import in a fresh one)."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import bayes_mpem.cli"], check=True)
    times = {"import (fresh process)": time.perf_counter() - t0}
    import bayes_mpem as bm
    from bayes_mpem.io.results import write_json, write_table, writing

    t0 = time.perf_counter()
    survey = bm.load_survey(folder / f"pings.{fmt}", folder / "beacons.csv")
    times["read and validate"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = bm.fit(survey, rng=0)
    times["EM (both geometries, 4 beacons)"] = time.perf_counter() - t0
    with writing(out) as d:
        t0 = time.perf_counter()
        write_table(d / f"classified.{fmt}", res.classified())
        times[f"classified.{fmt}"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_json(d / "history.json", res.history(), indent=None)
        times["history.json"] = time.perf_counter() - t0
        write_json(d / "summary.json", res.summary())
    return times


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1_000_000, 10_000_000])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cache", default=str(Path(tempfile.gettempdir()) / "bayes_mpem_big"))
    ap.add_argument("--phases", action="store_true", help="also time the phases at each size")
    args = ap.parse_args()
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    load0 = os.getloadavg()
    rows = []
    for n in args.sizes:
        folder = make_data(n, cache)
        size = {f: (folder / f"pings.{f}").stat().st_size / 1e6 for f in ("csv", "parquet")}
        runs = {"csv": [], "parquet": []}
        with tempfile.TemporaryDirectory(dir=cache) as tmp:
            for k in range(args.repeats):
                for fmt in ("parquet", "csv") if k % 2 else ("csv", "parquet"):
                    runs[fmt].append(run_fit(folder, fmt, Path(tmp) / f"{fmt}{k}"))
            for fmt in ("csv", "parquet"):
                secs = [s for s, _ in runs[fmt]]
                mem = max(m for _, m in runs[fmt])
                rows.append((n, fmt, size[fmt], statistics.median(secs), min(secs), max(secs),
                             mem))
                print(f"{n:>10,} rows {fmt:<8} {size[fmt]:7.0f} MB in: median "
                      f"{statistics.median(secs):6.1f} s (min {min(secs):.1f}, max "
                      f"{max(secs):.1f}), peak RSS {mem:7.0f} MB", flush=True)
            if args.phases:
                for fmt in ("csv", "parquet"):
                    for name, s in phases(folder, fmt, Path(tmp) / f"ph_{fmt}").items():
                        print(f"    {fmt:<8} {name:<34} {s:6.2f} s", flush=True)
    load1 = os.getloadavg()
    print(f"\nload average before {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, after "
          f"{load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}; {os.cpu_count()} cores")
    print("\n| rows | input | input MB | fit end to end, median s (min-max) | peak RSS MB |")
    print("|---|---|---|---|---|")
    for n, fmt, mb, med, lo, hi, mem in rows:
        print(f"| {n:,} | {fmt} | {mb:.0f} | {med:.1f} ({lo:.1f}-{hi:.1f}) | {mem:.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
