"""Killing a command at any moment never leaves a complete-looking but wrong folder (issue 15).

Real ``bayes-mpem`` processes rewrite a folder that already holds a complete earlier run
and are killed (SIGKILL at a random moment and as the writing starts, SIGTERM as it
starts). Afterwards the folder must either hold the earlier complete results, byte for
byte, or no ``summary.json`` at all (nothing that looks complete); a ``summary.json`` present
must list only files that exist. On f31dfee a killed ``sample`` left an unreadable
posterior.nc beside the earlier summary.json and classified.csv, and a killed ``demo`` a
complete-looking top level.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

BIN = [sys.executable, "-c", "import sys; from bayes_mpem.cli import main; sys.exit(main())"]


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.startswith(".")}


def _check_folder(folder: Path, previous: dict, where: str) -> str:
    """'previous' (the earlier run, intact), 'new' (a complete new run) or 'incomplete'."""
    now = _snapshot(folder)
    markers = [k for k in now if k.endswith("summary.json")]
    top = now.get("summary.json")
    if top is None:
        # nothing complete at the top; no sub-folder may claim completeness over a mix either
        for m in markers:
            doc = json.loads(now[m])
            base = Path(m).parent
            assert all((folder / base / f).exists() for f in doc.get("files", [])), where
        return "incomplete"
    doc = json.loads(top)  # valid JSON
    if now == previous:
        return "previous"
    files = doc.get("files")
    changed = sorted(k for k in now if now[k] != previous.get(k))
    assert files is not None, (f"{where}: the folder changed ({changed}) but its summary.json "
                               "still looks complete")
    assert all((folder / f).exists() for f in files), f"{where}: a listed file is missing"
    return "new"


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    out = tmp_path_factory.mktemp("kill")
    subprocess.run([*BIN, "simulate", "--preset", "abe58", "--seed", "2", "--n-cycles", "80",
                    "--out", str(out / "sim")], check=True, capture_output=True)
    two = out / "two"  # two beacons: shorter runs, the same writing
    two.mkdir()
    lines = (out / "sim" / "pings.csv").read_text().splitlines()
    (two / "pings.csv").write_text("\n".join(
        [lines[0]] + [ln for ln in lines[1:] if ln.split(",")[1] in ("1", "2")]) + "\n")
    (two / "beacons.csv").write_text("\n".join(
        (out / "sim" / "beacons.csv").read_text().splitlines()[:3]) + "\n")
    return two


def _touched(folder: Path, since: float) -> bool:
    for p in folder.rglob("*"):
        try:
            if p.is_file() and p.stat().st_mtime >= since:
                return True
        except FileNotFoundError:  # renamed meanwhile: the run is writing
            return True
    return False


def _kill_runs(argv, folder: Path, moments, full_seconds):
    """Run ``argv`` (writing ``folder``) and kill it at each ``(signal, moment)``: a fraction
    of its full run time, or ``"writing"`` (the moment its first file appears)."""
    previous = _snapshot(folder)
    seen = []
    for sig, frac in moments:
        start = time.time()
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        if frac == "writing":  # the moment the first file of the new run appears
            while proc.poll() is None and not _touched(folder, start):
                time.sleep(0.002)
        else:
            time.sleep(frac * full_seconds)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        when = frac if isinstance(frac, str) else f"{frac:.2f} of the run"
        where = f"{sig.name} at {when} (exit {proc.returncode})"
        assert b"Traceback" not in err, where
        state = _check_folder(folder, previous, where)
        seen.append(state)
        if state == "new":
            previous = _snapshot(folder)
    return seen


def _timed(argv):
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True)
    return time.perf_counter() - t0


@pytest.mark.slow
@pytest.mark.parametrize("command", ["sample", "diagnose", "demo"])
def test_killed_runs_leave_the_previous_results_or_nothing_complete(survey, tmp_path, command):
    out = tmp_path / "out"
    argv = {"sample": [*BIN, "sample", str(survey / "pings.csv"), "--beacons",
                       str(survey / "beacons.csv"), "--out", str(out), "--no-progress",
                       "--min-pings", "30"],
            "diagnose": [*BIN, "diagnose", str(survey / "pings.csv"), "--beacons",
                         str(survey / "beacons.csv"), "--out", str(out), "--no-progress",
                         "--effects", "range_bias,plane_drift", "--folds", "2"],
            "demo": [*BIN, "demo", "--no-bayes", "--out", str(out)]}[command]
    full = _timed(argv)  # a complete earlier run in the folder
    assert (out / "summary.json").exists()
    rng = np.random.default_rng(sum(map(ord, command)))
    # SIGKILL at a random moment and at the start of the writing; SIGTERM (no handler in the
    # package: Python dies at once, as on SIGKILL) at the start of the writing only
    moments = [(signal.SIGKILL, float(rng.uniform(0.3, 1.0))), (signal.SIGKILL, "writing"),
               (signal.SIGTERM, "writing")]
    states = _kill_runs(argv, out, moments, full)
    assert set(states) <= {"previous", "new", "incomplete"}


def test_a_reader_that_leaves_does_not_discard_the_results(tmp_path):
    """``bayes-mpem locate ... | true``: the printing failed with a broken pipe after the fit
    and the all-or-nothing folder was discarded (exit 2; found by a review). Now the output
    is dropped and the files are written; no error, no traceback at exit."""
    from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa

    site = simulate_gnssa(hours=0.3, rng=2).write(tmp_path / "sim")["survey"]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # a pipe's buffer
    run = subprocess.Popen([*BIN, "locate", str(site), "--out", str(tmp_path / "out")],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    run.stdout.close()  # the reader leaves before the first line
    with run.stderr:
        err = run.stderr.read().decode()
    assert run.wait(timeout=120) == 0, err
    assert "Broken pipe" not in err and "Traceback" not in err and "Exception" not in err
    assert {p.name for p in (tmp_path / "out").iterdir()} >= {"summary.json", "classified.csv",
                                                              "solution.txt"}


def test_ctrl_c_while_the_command_loads_says_interrupted_without_a_traceback(monkeypatch,
                                                                               capsys):
    """Ctrl-C in the first second (the command's modules loading) printed a traceback."""
    from bayes_mpem.cli import main, parser

    real = parser.load

    def loading(name):
        if name.endswith(":cmd_locate"):  # the command's modules, not the options'
            raise KeyboardInterrupt
        return real(name)

    monkeypatch.setattr(parser, "load", loading)
    assert main(["locate", "nowhere.ini", "--out", "nowhere"]) == 130
    err = capsys.readouterr().err
    assert "interrupted; no result written" in err and "Traceback" not in err


CC03 = Path(__file__).resolve().parents[2] / "data" / "obsrange" / "SIO_CC03.txt"


@pytest.mark.parametrize("how", ["raised", "signal"])
def test_ctrl_c_after_the_commit_reports_the_result_written(tmp_path, monkeypatch, capsys,
                                                            how):
    """A Ctrl-C in the last ~0.3 s of a run, once its files were in place, exited 130 with
    "interrupted; no result written" over a complete new result (session 47). Now the state
    and the status agree: the result is written, status 0; the caller's handler comes back."""
    from bayes_mpem.cli import main
    from bayes_mpem.io import results

    argv = ["locate", str(CC03), "--format", "obsrange", "--out", str(tmp_path / "out")]
    assert main(argv) == 0
    earlier = (tmp_path / "out" / "summary.json").stat().st_mtime_ns
    real = results._Run._clean_dead_partials

    def after_the_commit(run):  # the commit's last step, every file in place
        if how == "raised":
            raise KeyboardInterrupt
        signal.raise_signal(signal.SIGINT)  # a real Ctrl-C
        real(run)

    monkeypatch.setattr(results._Run, "_clean_dead_partials", after_the_commit)
    capsys.readouterr()
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "interrupted" not in err and "Traceback" not in err
    assert (tmp_path / "out" / "summary.json").stat().st_mtime_ns > earlier
    doc = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert all((tmp_path / "out" / f).exists() for f in doc["files"])
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.parametrize("when", ["after", "before"])
def test_sigterm_after_the_commit_reports_the_result_written(tmp_path, monkeypatch, capsys, when):
    """A SIGTERM once the files were in place said "terminated; no result written" (143)
    over the new, complete folder; before the commit it still does."""
    from bayes_mpem.cli import main, parser
    from bayes_mpem.io import results

    def exit_(code):
        raise SystemExit(code)

    monkeypatch.setattr(parser.os, "_exit", exit_)
    real = results._Run._clean_dead_partials if when == "after" else results._Run.commit

    def term(run):
        if when == "after":
            real(run)
        parser._on_sigterm(signal.SIGTERM, None)  # what the handler does on a SIGTERM

    monkeypatch.setattr(results._Run, "_clean_dead_partials" if when == "after" else "commit",
                        term)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        main(["locate", str(CC03), "--format", "obsrange", "--out", str(out)])
    err = capsys.readouterr().err
    if when == "after":
        assert stop.value.code == 0
        assert f"terminated after its result was written to {out}" in err
        doc = json.loads((out / "summary.json").read_text())
        assert all((out / f).exists() for f in doc["files"])
    else:
        assert stop.value.code == 128 + signal.SIGTERM
        assert "terminated; no result written" in err
        assert not (out / "summary.json").exists()


def test_ctrl_c_before_the_commit_still_writes_nothing(tmp_path, monkeypatch, capsys):
    from bayes_mpem.cli import main
    from bayes_mpem.io import results

    def before_the_commit(run):
        raise KeyboardInterrupt

    monkeypatch.setattr(results._Run, "commit", before_the_commit)
    argv = ["locate", str(CC03), "--format", "obsrange", "--out", str(tmp_path / "out")]
    assert main(argv) == 130
    assert "interrupted; no result written" in capsys.readouterr().err
    assert not (tmp_path / "out" / "summary.json").exists()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.slow
def test_a_real_ctrl_c_as_the_process_ends_keeps_status_0(survey, tmp_path):
    """The process outlives its commit by some 0.5 s (the interpreter's exit); a SIGINT there
    killed it (status -2, 130 in a shell) or printed "interrupted; no result written" over the
    new, complete folder. Each SIGINT here comes once the new summary.json is in place."""
    out = tmp_path / "out"
    argv = [*BIN, "sample", str(survey / "pings.csv"), "--beacons", str(survey / "beacons.csv"),
            "--out", str(out), "--no-progress", "--min-pings", "30", "--min-ess", "200"]
    subprocess.run(argv, check=True, capture_output=True)
    for delay in (0.0, 0.05):
        before = (out / "summary.json").stat().st_ino
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        while proc.poll() is None:
            try:
                if (out / "summary.json").stat().st_ino != before:
                    break
            except FileNotFoundError:  # unlinked for the commit
                pass
            time.sleep(0.0005)
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, (delay, proc.returncode, err.decode())
        assert b"interrupted" not in err and b"Traceback" not in err
        assert (out / "summary.json").stat().st_ino != before
