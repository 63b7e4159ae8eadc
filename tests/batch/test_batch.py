"""bayes-mpem batch: same results as each dive alone, failures recorded, resumable."""

import json

import pandas as pd
import pytest

from bayes_mpem.batch import BatchTask, flatten, read_manifest, run_batch
from bayes_mpem.cli import main
from bayes_mpem.cli.batch import tasks_from_manifest
from bayes_mpem.cli.parser import build_parser
from bayes_mpem.exceptions import InputError
from bayes_mpem.io.formats import sample_file

N_DIVES = 3


@pytest.fixture(scope="module")
def dives(tmp_path_factory):
    """Three small simulated dives and a manifest (one with an option column)."""
    root = tmp_path_factory.mktemp("dives")
    for i in range(N_DIVES):
        assert main(["simulate", "--seed", str(i), "--n-cycles", "250",
                     "--out", str(root / f"d{i}")]) == 0
    rows = ["name,pings,beacons,sigma_dp"] + [
        f"dive{i},d{i}/pings.csv,d{i}/beacons.csv,{'3.97' if i == 1 else ''}"
        for i in range(N_DIVES)]
    (root / "manifest.csv").write_text("\n".join(rows) + "\n")
    return root


@pytest.fixture(scope="module")
def scheduler():
    """One local cluster for the module (two worker processes), passed as --scheduler."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=40) as cluster:
        yield cluster.scheduler_address


def _wait_idle(address):
    import time

    from distributed import Client

    with Client(address) as client:
        while any(client.processing().values()):
            time.sleep(0.05)


def _tasks(manifest, command="fit"):
    return tasks_from_manifest(manifest, command, build_parser().get_default("subparsers"))


def test_same_results_as_each_dive_alone(dives, scheduler, tmp_path):
    out = tmp_path / "batch"
    result = run_batch(_tasks(dives / "manifest.csv"), out, scheduler=scheduler,
                       progress=False)
    assert list(result.surveys["status"]) == ["done"] * N_DIVES
    assert result.failures.empty
    for i in range(N_DIVES):
        alone = tmp_path / f"alone{i}"
        extra = ["--sigma-dp", "3.97"] if i == 1 else []
        assert main(["fit", str(dives / f"d{i}" / "pings.csv"), "--beacons",
                     str(dives / f"d{i}" / "beacons.csv"), "--out", str(alone), *extra]) == 0
        mine = out / "surveys" / f"dive{i}"
        for name in ("summary.json", "classified.csv"):  # byte for byte
            assert (mine / name).read_bytes() == (alone / name).read_bytes(), name
        summary = json.loads((alone / "summary.json").read_text())
        rows = result.beacons[result.beacons["name"] == f"dive{i}"].set_index("beacon")
        for bid, b in summary["beacons"].items():
            assert rows.loc[bid, "d0"] == b["d0"]
            assert rows.loc[bid, "weights_mp"] == b["weights"]["mp"]
    # the gathered files: one row per survey x beacon, classified pings by survey
    table = pd.read_parquet(out / "beacons.parquet")
    assert len(table) == 4 * N_DIVES and {"name", "beacon", "d0", "sigma_mp"} <= set(table)
    classified = pd.read_parquet(out / "classified")
    assert sorted(classified["name"].astype(str).unique()) == [f"dive{i}" for i in range(3)]
    n_rows = sum(len(pd.read_csv(dives / f"d{i}" / "pings.csv")) for i in range(N_DIVES))
    assert len(classified) == n_rows
    assert (result.beacons.loc[result.beacons["name"] == "dive1", "sigma_dp"] == 3.97).all()


def test_a_failing_dive_is_recorded_and_the_others_complete(dives, scheduler, tmp_path):
    tasks = _tasks(dives / "manifest.csv")
    broken = tmp_path / "broken.csv"
    broken.write_text("time,beacon,range,x,y,depth\n0,1,abc,0,0,10\n")
    tasks[1] = BatchTask("dive1", "fit", {**tasks[1].inputs, "pings": str(broken)},
                         tasks[1].options)
    result = run_batch(tasks, tmp_path / "out", scheduler=scheduler, progress=False)
    assert list(result.surveys["status"]) == ["done", "failed", "done"]
    [reason] = result.failures["reason"]
    assert result.failures["name"].tolist() == ["dive1"]
    assert reason.startswith("InputError") and "broken.csv" in reason and "range" in reason
    assert set(result.beacons["name"]) == {"dive0", "dive2"}
    assert pd.read_parquet(tmp_path / "out" / "failures.parquet")["name"].tolist() == ["dive1"]
    assert not (tmp_path / "out" / "surveys" / "dive1" / "batch.json").exists()


def test_an_interrupted_batch_resumes_without_redoing_finished_dives(dives, scheduler,
                                                                     tmp_path):
    out = tmp_path / "out"
    tasks = _tasks(dives / "manifest.csv")

    def interrupt(record, done, total):
        raise KeyboardInterrupt  # Ctrl-C after the first survey is complete

    with pytest.raises(KeyboardInterrupt):
        run_batch(tasks, out, scheduler=scheduler, report=interrupt)
    _wait_idle(scheduler)  # a task already running on a shared cluster may still finish
    finished = [t.name for t in tasks if (out / "surveys" / t.name / "batch.json").exists()]
    assert len(finished) >= 1
    stamps = {n: (out / "surveys" / n / "summary.json").stat().st_mtime_ns for n in finished}
    result = run_batch(tasks, out, scheduler=scheduler, progress=False)
    status = dict(zip(result.surveys["name"], result.surveys["status"], strict=True))
    assert all(status[n] == "complete" for n in finished)
    assert all(status[t.name] == "done" for t in tasks if t.name not in finished)
    assert {n: (out / "surveys" / n / "summary.json").stat().st_mtime_ns
            for n in finished} == stamps  # not redone
    assert len(result.beacons) == 4 * N_DIVES
    # a changed option changes the content hash: that dive alone is redone
    tasks[0] = BatchTask(tasks[0].name, "fit", tasks[0].inputs,
                         {**tasks[0].options, "min_pings": 20})
    again = run_batch(tasks, out, scheduler=scheduler, progress=False)
    assert list(again.surveys["status"]) == ["done", "complete", "complete"]


def test_batch_command_with_a_local_cluster_and_locate(tmp_path, capsys):
    """The command line end to end: its own local cluster, survey-in, exit status."""
    cc03 = sample_file("obsrange/SIO_CC03.txt")
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"name,survey,format,ci\ncc03,{cc03},obsrange,0.9\n"
                        f"gone,{tmp_path / 'nope.txt'},obsrange,\n")
    status = main(["batch", str(manifest), "--out", str(tmp_path / "o"), "--command",
                   "locate", "--workers", "2"])
    assert status == 1  # one survey failed
    captured = capsys.readouterr()
    assert "1 done, 0 already complete, 1 failed" in captured.out
    # the manifest's line and column of the file not found
    assert f"gone: InputError: {manifest} line 3, column 'survey': " in captured.err
    assert "nope.txt not found" in captured.err
    table = pd.read_parquet(tmp_path / "o" / "beacons.parquet")
    assert table["name"].tolist() == ["cc03"] and "depth_mean" in table
    assert json.loads((tmp_path / "o" / "surveys" / "cc03" / "summary.json").read_text())
    # plot draws every complete survey of a batch folder
    assert main(["plot", str(tmp_path / "o"), "--out", str(tmp_path / "figs")]) == 0
    assert (tmp_path / "figs" / "surveys" / "cc03" / "survey_map.png").stat().st_size > 0
    assert not (tmp_path / "figs" / "surveys" / "gone").exists()
    assert main(["plot", str(tmp_path / "o"), "--beacon", "1"]) == 2
    assert "--beacon: draws one survey's beacon" in capsys.readouterr().err


@pytest.mark.parametrize(("rows", "message"), [
    ("name,pings\nd,p.csv\n", "needs the columns name, pings, beacons; missing: beacons"),
    ("name,pings,beacons\nd,p.csv,b.csv\nd,p.csv,b.csv\n", "line 3, column 'name': 'd' already"),
    ("name,pings,beacons\na/b,p.csv,b.csv\n", "line 2, column 'name': expected a plain"),
    ("name,pings,beacons\nd,,b.csv\n", "line 2, column 'pings': expected a value"),
    ("name,pings,beacons,method\nd,p.csv,b.csv,nope\n", "line 2: argument --method: invalid"),
    ("name,pings,beacons,pol\nd,p.csv,b.csv,0.1\n", "line 2: --pol and --alpha apply to"),
    ("name,pings,beacons,figures\nd,p.csv,b.csv,1\n", "column 'figures': not an option of"),
])
def test_manifest_is_checked_before_any_work(tmp_path, rows, message, capsys):
    manifest = tmp_path / "m.csv"
    manifest.write_text(rows)
    with pytest.raises(InputError, match=message):
        _tasks(manifest)
    assert main(["batch", str(manifest), "--out", str(tmp_path / "o")]) == 2
    assert "bayes-mpem batch: error:" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_read_manifest_resolves_paths_and_keeps_option_columns(tmp_path):
    (tmp_path / "m.csv").write_text("name,pings,beacons,seed\nd1,x/p.csv,/abs/b.csv,3\n")
    [task], options = read_manifest(tmp_path / "m.csv", "fit")
    assert task.inputs == {"pings": str((tmp_path / "x" / "p.csv").resolve()),
                           "beacons": "/abs/b.csv"}
    assert options.to_dict("records") == [{"seed": "3"}]


def test_flatten_keeps_every_field():
    row = flatten({"d0": {"mean": 1.0, "sd": 0.1, "interval": [0.8, 1.2]},
                   "weights": {"dp": 0.5}, "flags": ["a"], "n": 3, "path_choice": None})
    assert row == {"d0_mean": 1.0, "d0_sd": 0.1, "d0_interval_0": 0.8, "d0_interval_1": 1.2,
                   "weights_dp": 0.5, "flags": '["a"]', "n": 3, "path_choice": None}


def test_every_batch_command_has_its_option_builder():
    """A batch command is one entry of the command table: its builder, call and rows load."""
    from bayes_mpem.batch import COMMANDS
    from bayes_mpem.commands import load

    assert set(COMMANDS) == {"fit", "sample", "diagnose", "locate", "navigate"}
    for spec in COMMANDS.values():
        assert all(callable(load(name)) for name in (spec.kwargs, spec.run, spec.rows))
        assert set(spec.files) <= set(spec.inputs)
    batch = build_parser().parse_args(["batch", "m.csv", "--out", "o"])
    assert batch.batch_command == "fit"
    assert set(batch.subparsers["batch"]._option_string_actions["--command"].choices) == set(
        COMMANDS)


def test_navigate_in_a_batch_gives_the_same_files_as_alone(scheduler, tmp_path):
    dive = tmp_path / "dive"
    assert main(["simulate", "--navigation", "--seed", "2", "--n-cycles", "200",
                 "--out", str(dive)]) == 0
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"name,pings,beacons,model\nd,{dive / 'pings.csv'},"
                        f"{dive / 'beacons.csv'},mixture\n")
    result = run_batch(_tasks(manifest, "navigate"), tmp_path / "out", scheduler=scheduler,
                       progress=False)
    assert result.failures.empty, result.failures
    assert main(["navigate", str(dive / "pings.csv"), "--beacons", str(dive / "beacons.csv"),
                 "--out", str(tmp_path / "alone")]) == 0
    for name in ("summary.json", "classified.csv", "track.csv"):
        assert ((tmp_path / "out" / "surveys" / "d" / name).read_bytes()
                == (tmp_path / "alone" / name).read_bytes()), name
    assert {"name", "beacon", "d0_estimate"} <= set(result.beacons)


def test_a_manifest_column_gives_an_array_its_noise_correlation(tmp_path):
    """``correlation`` is a column like any option: parsed by ``locate``'s own parser."""
    survey = tmp_path / "site-initcfg.ini"
    survey.write_text("")  # the manifest is parsed, not run
    manifest = tmp_path / "m.csv"
    manifest.write_text(f'name,survey,format,correlation\na,{survey},garpos,"60,0.5,0.3"\n'
                        f"b,{survey},garpos,off\nc,{survey},garpos,\n")
    tasks = _tasks(manifest, "locate")
    assert [t.options["correlation"] for t in tasks] == [(60.0, 0.5, 0.3), "off", "auto"]
    manifest.write_text(f"name,survey,format,correlation\na,{survey},garpos,60s\n")
    with pytest.raises(InputError, match=r"m.csv line 2: argument --correlation: .*'60s'"):
        _tasks(manifest, "locate")


def test_a_task_made_in_python_names_its_missing_input(scheduler, tmp_path):
    task = BatchTask("t", "locate", {"survey": str(tmp_path / "nope.txt"), "format": "obsrange"})
    result = run_batch([task], tmp_path / "out", scheduler=scheduler, progress=False)
    assert result.failures["reason"].tolist() == [
        f"InputError: t: input 'survey': {tmp_path / 'nope.txt'} not found"]


def _files(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_an_interrupted_rerun_keeps_the_unfinished_surveys_and_no_stale_tables(
        dives, scheduler, tmp_path):
    """Ctrl-C while a changed batch runs: the survey collected before it is this run's, every
    other keeps its earlier folder (tasks still running on the cluster do not replace it, nor
    record it failed), and the earlier top-level tables, which no longer match, are gone."""
    out = tmp_path / "out"
    tasks = _tasks(dives / "manifest.csv")
    first = run_batch(tasks, out, scheduler=scheduler, progress=False)
    assert list(first.surveys["status"]) == ["done"] * N_DIVES
    before = {t.name: _files(out / "surveys" / t.name) for t in tasks}
    parts = {t.name: (out / "classified" / f"survey-{t.name}.parquet").read_bytes()
             for t in tasks}
    changed = [BatchTask(t.name, "fit", t.inputs, {**t.options, "sigma_dp": 2.5}) for t in tasks]
    collected = []

    def interrupt(record, done, total):
        collected.append(record["name"])
        raise KeyboardInterrupt  # Ctrl-C after the first survey is complete

    with pytest.raises(KeyboardInterrupt):
        run_batch(changed, out, scheduler=scheduler, report=interrupt)
    _wait_idle(scheduler)  # the tasks already running on the shared cluster finish
    [new] = collected
    for t in tasks:
        folder = out / "surveys" / t.name
        assert not (folder / "failed.json").exists(), t.name
        part = (out / "classified" / f"survey-{t.name}.parquet").read_bytes()
        if t.name == new:
            record = json.loads((folder / "batch.json").read_text())
            assert record["hash"] == changed[[c.name for c in changed].index(new)].key()
            assert (folder / "summary.json").read_bytes() != before[t.name]["summary.json"]
            assert part != parts[t.name]
        else:  # as the earlier run left it, byte for byte
            assert _files(folder) == before[t.name], t.name
            assert part == parts[t.name], t.name
    # the earlier tables listed the earlier results of the survey now redone
    for name in ("summary.json", "surveys.parquet", "beacons.parquet", "failures.parquet"):
        assert not (out / name).exists(), name
    # a task still running on the shared cluster may stage its run after the batch stopped
    # (never put in place); the next run clears what is left
    again = run_batch(changed, out, scheduler=scheduler, progress=False)  # resumes
    assert not (out / ".batch-partial").exists()
    (out / ".batch-partial" / "stray").mkdir(parents=True)  # and one with nothing to run
    run_batch(changed, out, scheduler=scheduler, progress=False)
    assert not (out / ".batch-partial").exists()
    status = dict(zip(again.surveys["name"], again.surveys["status"], strict=True))
    assert status == {t.name: "complete" if t.name == new else "done" for t in tasks}
    table = pd.read_parquet(out / "surveys.parquet")
    assert table["hash"].tolist() == [c.key() for c in changed]


def test_ctrl_c_names_the_surveys_kept(dives, scheduler, tmp_path, monkeypatch, capsys):
    """After Ctrl-C the batch printed "interrupted; no result written" although the surveys
    collected before it were kept (with their batch.json, for the next run)."""
    import bayes_mpem.batch.runner as runner

    real = runner._report

    def interrupt(record, done, total):
        real(record, done, total)
        raise KeyboardInterrupt  # Ctrl-C after the first survey is put in place

    monkeypatch.setattr(runner, "_report", interrupt)
    out = tmp_path / "out"
    assert main(["batch", str(dives / "manifest.csv"), "--out", str(out),
                 "--scheduler", scheduler]) == 130
    _wait_idle(scheduler)
    err = capsys.readouterr().err
    [kept] = [p.parent.name for p in (out / "surveys").glob("*/batch.json")]
    assert "no result written" not in err and "Traceback" not in err
    assert (f"interrupted; the 1 survey collected before it is kept in {out / 'surveys'}: "
            f"{kept} (done); the 2 not collected keep their earlier folders") in err


def test_a_task_cancelled_by_the_scheduler_is_not_a_failure(dives, scheduler, tmp_path):
    """A scheduler that cancels the tasks (restarted, closed) stops the batch with a message;
    the surveys not collected keep their earlier folders and none is recorded failed."""
    from distributed import Future, default_client

    out = tmp_path / "out"
    tasks = _tasks(dives / "manifest.csv")
    run_batch(tasks, out, scheduler=scheduler, progress=False)
    before = {t.name: _files(out / "surveys" / t.name) for t in tasks}
    changed = [BatchTask(t.name, "fit", t.inputs, {**t.options, "sigma_dp": 2.5}) for t in tasks]
    collected = []

    def cancel_the_rest(record, done, total):
        collected.append(record["name"])
        if len(collected) == 1:
            client = default_client()
            client.cancel([Future(k, client) for k in list(client.futures)])

    with pytest.raises(InputError, match=r"survey 'dive\d': its task was cancelled by the "
                                         r"Dask scheduler \(tcp://.*run the batch again"):
        run_batch(changed, out, scheduler=scheduler, report=cancel_the_rest)
    _wait_idle(scheduler)
    assert len(collected) == 1
    for t in tasks:
        if t.name not in collected:
            assert _files(out / "surveys" / t.name) == before[t.name], t.name


def test_an_array_in_a_batch_keeps_its_centre_and_says_when_one_is_missing(scheduler, tmp_path):
    """A hunt (session 48): a campaign whose M04 never replied was 'done' with 0 warnings,
    and no gathered table held the array centre or its 'not comparable' note (a centre
    averaged from beacons.parquet was 250 m from the full array's)."""
    from bayes_mpem.io.garpos import write_garpos
    from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa

    sim = simulate_gnssa(hours=0.5, rng=3)
    full = write_garpos(tmp_path / "full", sim.pings, sim.header)
    some = write_garpos(tmp_path / "some", sim.pings[sim.pings["transponder"] != "M04"],
                        sim.header)
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"name,survey,format\nfull,{full},garpos\nsome,{some},garpos\n")
    result = run_batch(_tasks(manifest, "locate"), tmp_path / "out", scheduler=scheduler,
                       progress=False)
    s = result.surveys.set_index("name")
    assert list(s["status"]) == ["done", "done"]
    assert s.loc["full", "centre_note"] == "" and s.loc["full", "centre_transponders"] == (
        "M01,M02,M03,M04")
    assert s.loc["some", "centre_note"].startswith("the mean of M01, M02, M03 only (M04 not "
                                                   "located): not comparable")
    assert s.loc["some", "n_warnings"] >= 1
    assert "1 transponder not located (M04: 0 shots" in s.loc["some", "warnings"]
    assert abs(s.loc["full", "centre_enu_up_mean"]
               - sim.truth_record()["array_centre"]["up"]) < 0.1
    # a review: a rerun over the records of an earlier version (no fields) kept no centre
    for name in ("full", "some"):
        done = tmp_path / "out" / "surveys" / name / "batch.json"
        record = json.loads(done.read_text())
        del record["fields"]
        done.write_text(json.dumps(record))
    again = run_batch(_tasks(manifest, "locate"), tmp_path / "out", scheduler=scheduler,
                      progress=False).surveys.set_index("name")
    assert list(again["status"]) == ["done", "done"]  # run again, not taken as complete
    assert again.loc["some", "centre_note"] == s.loc["some", "centre_note"]
    third = run_batch(_tasks(manifest, "locate"), tmp_path / "out", scheduler=scheduler,
                      progress=False).surveys.set_index("name")
    assert list(third["status"]) == ["complete", "complete"]
    assert third.loc["full", "centre_transponders"] == "M01,M02,M03,M04"
