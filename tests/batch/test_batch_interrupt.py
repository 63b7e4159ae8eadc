"""Ctrl-C during a real ``bayes-mpem batch`` that redoes surveys (a local cluster).

On bd5ef50 the survey running at the interrupt lost its earlier complete results: its task
had removed its folder first, then failed as the cluster shut down (``failed.json``:
"RuntimeError: ConnectionPool is closed", from the netCDF writer's Dask lock), while the
earlier ``surveys.parquet`` and ``beacons.parquet`` still listed it as done, with the
earlier values of the survey already redone.
"""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from bayes_mpem.cli import main

BIN = [sys.executable, "-c", "import sys; from bayes_mpem.cli import main; sys.exit(main())"]
NAMES = ("d1", "d2", "d3")


def _files(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


@pytest.mark.slow
def test_ctrl_c_keeps_the_running_survey_and_leaves_no_stale_tables(tmp_path):
    for i, name in enumerate(NAMES, start=1):
        assert main(["simulate", "--preset", "random", "--seed", str(i), "--n-cycles", "400",
                     "--out", str(tmp_path / name)]) == 0
    rows = "".join(f"{n},{n}/pings.csv,{n}/beacons.csv,{{seed}}\n" for n in NAMES)
    for seed in (0, 5):
        (tmp_path / f"m{seed}.csv").write_text("name,pings,beacons,seed\n"
                                               + rows.format(seed=seed))
    out = tmp_path / "out"

    def batch(seed, *more):
        return [*BIN, "batch", str(tmp_path / f"m{seed}.csv"), "--out", str(out),
                "--command", "sample", *more]

    subprocess.run(batch(0, "--no-progress"), check=True, capture_output=True)
    before = {n: _files(out / "surveys" / n) for n in NAMES}
    with subprocess.Popen(batch(5), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True) as proc:
        lines = []
        for line in proc.stderr:
            lines.append(line)
            if "d1: done" in line:  # d2 is running now
                proc.send_signal(signal.SIGINT)
                break
        err = "".join(lines) + proc.stderr.read()
        assert proc.wait(timeout=120) == 130, err
    assert "Traceback" not in err and "no result written" not in err
    assert "interrupted; the 1 survey collected before it is kept" in err and "d1 (done)" in err
    assert _files(out / "surveys" / "d1") != before["d1"]  # done before the interrupt: kept
    assert (out / "surveys" / "d1" / "batch.json").is_file()
    for name in ("d2", "d3"):  # interrupted or not started: the earlier results, intact
        assert _files(out / "surveys" / name) == before[name], name
        assert (out / "classified" / f"survey-{name}.parquet").is_file()
    # the earlier tables (d1's earlier values) are gone with their marker: nothing complete
    assert sorted(p.name for p in out.iterdir()) == ["classified", "surveys"]
    again = subprocess.run(batch(5, "--no-progress"), capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert "3 surveys: 2 done, 1 already complete, 0 failed" in again.stdout
