"""A live stream is never poisoned: a refused line changes nothing downstream.

The acceptance test of issue 27: a dive with one line each of ``x = 1e300``,
``time = 1e300``, ``time = -1e300`` (first), ``depth = -1e9`` and a time far
ahead mixed in gives, for every other line, the very answer of the dive without
them, also across a ``--state`` save and resume; and ``--out FILE`` is replaced
or appended to.
"""

import json
import os

import pytest

from bayes_mpem.cli import main
from bayes_mpem.lbl.navigate import simulate_dive


@pytest.fixture(scope="module")
def dive(tmp_path_factory):
    out = tmp_path_factory.mktemp("dive")
    simulate_dive("abe58", rng=5, n_cycles=60).write(out)
    return out, (out / "pings.csv").read_text().splitlines()


def _poisoned(lines):
    """The lines with bad ones mixed in: (lines, numbers of the bad lines, from 1)."""
    cols = lines[0].split(",")
    first = lines[1].split(",")

    def spoil(row, **kw):
        cells = row.split(",")
        for k, v in kw.items():
            cells[cols.index(k)] = v
        return ",".join(cells)

    bad = {1: spoil(lines[1], time="-1e300"),  # before the first good line
           30: spoil(lines[30], x="1e300"),  # inside the warm-up
           90: spoil(lines[90], time="1e300"),  # after it
           120: spoil(lines[120], depth="-1e9"),
           150: spoil(lines[150], time="99999"),  # within the limits, beyond --max-gap
           160: spoil(lines[160], range="1e300"),
           170: ",".join(first[:2]) + ',"1\r2",0,0,5',  # a bare CR inside a field
           180: spoil(lines[180], x="7" * 140000)}  # a field over 131,072 characters
    out, numbers = [lines[0]], []
    for i, line in enumerate(lines[1:], start=1):
        if i in bad:
            out.append(bad[i])
            numbers.append(len(out))
        out.append(line)
    return out, numbers


def _run(tmp_path, name, lines, beacons, *extra, speed="max"):
    src = tmp_path / f"{name}.csv"
    src.write_text("\n".join(lines) + "\n")
    out = tmp_path / f"{name}.jsonl"
    code = main(["stream", "--beacons", str(beacons), "--warmup", "60", "--replay", str(src),
                 "--speed", speed, "--out", str(out), *extra])
    assert code == 0
    return [json.loads(s) for s in out.read_text().splitlines()]


def _strip(answers):
    return [{k: v for k, v in a.items() if k != "line"} for a in answers if "error" not in a]


def test_bad_lines_change_nothing_downstream(dive, tmp_path, capsys):
    folder, lines = dive
    beacons = folder / "beacons.csv"
    clean = _run(tmp_path, "clean", lines, beacons)
    mixed, bad = _poisoned(lines)
    got = _run(tmp_path, "mixed", mixed, beacons)
    errors = {a["line"]: a["error"] for a in got if "error" in a}
    assert sorted(errors) == bad  # each bad line refused on its own line, and only those
    assert "column 'time'" in errors[bad[0]] and "column 'x'" in errors[bad[1]]
    assert "--max-gap" in errors[bad[4]]
    assert "carriage return" in errors[bad[6]]
    assert all(len(e) < 400 for e in errors.values())
    assert _strip(got) == _strip(clean)
    assert "Traceback" not in capsys.readouterr().err


def test_same_answers_across_a_state_save_and_resume(dive, tmp_path):
    folder, lines = dive
    beacons = folder / "beacons.csv"
    clean = _run(tmp_path, "clean", lines, beacons)
    mixed, _ = _poisoned(lines)
    state = tmp_path / "state.json"
    cut = 140  # after the warm-up, between two bad lines
    first = _run(tmp_path, "a", mixed[:cut], beacons, "--state", str(state))
    saved = json.loads(state.read_text())
    assert saved["phase"] == "online" and abs(saved["last"][0]) < 1e6
    second = _run(tmp_path, "b", [mixed[0], *mixed[cut:]], beacons, "--state", str(state))
    assert _strip(first) + _strip(second) == _strip(clean)


def test_out_file_is_replaced_or_appended(dive, tmp_path):
    folder, lines = dive
    beacons = folder / "beacons.csv"
    short = lines[:21]
    once = _run(tmp_path, "s", short, beacons)
    again = _run(tmp_path, "s", short, beacons)  # the same --out FILE: replaced
    assert again == once
    both = _run(tmp_path, "s", short, beacons, "--append")
    assert both == once + once


def test_out_is_never_one_of_the_inputs(dive, tmp_path, capsys, monkeypatch):
    """An --out FILE that is an input would be emptied before it is read."""
    folder, lines = dive
    beacons = tmp_path / "beacons.csv"
    beacons.write_text((folder / "beacons.csv").read_text())
    pings = tmp_path / "pings.csv"
    pings.write_text("\n".join(lines[:21]) + "\n")
    state = tmp_path / "state.json"
    state.write_text("{}")
    before = {p: p.read_text() for p in (beacons, pings, state)}
    runs = {"--beacons": ["--replay", str(pings), "--speed", "max", "--out", str(beacons)],
            "--replay": ["--replay", str(pings), "--speed", "max", "--out", str(pings)],
            "--state": ["--replay", str(pings), "--speed", "max", "--state", str(state),
                        "--out", str(state)]}
    for option, extra in runs.items():
        assert main(["stream", "--beacons", str(beacons), *extra]) == 2, option
        err = capsys.readouterr().err
        assert f"the same file as {option}" in err and "Traceback" not in err
    with open(pings) as stdin:  # ... < pings.csv --out pings.csv
        monkeypatch.setattr("sys.stdin", stdin)
        assert main(["stream", "--beacons", str(beacons), "--out", str(pings)]) == 2
    assert "the file standard input reads" in capsys.readouterr().err
    assert {p: p.read_text() for p in before} == before  # nothing lost
    # a link to an input is the same file
    link = tmp_path / "link.csv"
    link.symlink_to(pings)
    assert main(["stream", "--beacons", str(beacons), "--replay", str(pings), "--speed", "max",
                 "--out", str(link)]) == 2
    assert pings.read_text() == before[pings]
    # a device read and written is not a file to lose: ... --out /dev/null < /dev/null
    with open(os.devnull) as stdin:
        monkeypatch.setattr("sys.stdin", stdin)
        assert main(["stream", "--beacons", str(beacons), "--out", os.devnull]) == 0


def test_a_bad_state_is_refused_naming_the_file_and_the_option(dive, tmp_path, capsys):
    folder, lines = dive
    beacons = folder / "beacons.csv"
    state = tmp_path / "state.json"
    _run(tmp_path, "a", lines[:100], beacons, "--state", str(state))
    good = json.loads(state.read_text())
    src = tmp_path / "more.csv"
    src.write_text("\n".join([lines[0], *lines[100:110]]) + "\n")
    spoilers = {"no filter": lambda d: d.pop("filter"),
                "no options": lambda d: d.pop("options"),
                "null covariance": lambda d: d["filter"]["cov"].update(xx=None),
                "string x": lambda d: d["filter"].update(x="a"),
                "bad model": lambda d: next(iter(d["models"].values())).update(d0=None)}
    for name, spoil in spoilers.items():
        d = json.loads(json.dumps(good))
        spoil(d)
        state.write_text(json.dumps(d))
        code = main(["stream", "--beacons", str(beacons), "--replay", str(src), "--speed", "max",
                     "--state", str(state), "--out", str(tmp_path / "o.jsonl")])
        err = capsys.readouterr().err
        assert code == 2, name
        assert "--state" in err and str(state) in err and "internal error" not in err, name
        assert json.loads(state.read_text()) == d  # the bad state is left as it was
    state.write_text(json.dumps(good).replace('"x": ' + json.dumps(good["filter"]["x"]),
                                              '"x": NaN', 1))
    assert main(["stream", "--beacons", str(beacons), "--replay", str(src), "--speed", "max",
                 "--state", str(state), "--out", str(tmp_path / "o.jsonl")]) == 2
    assert "NaN" in capsys.readouterr().err


def test_replay_at_speed_with_a_huge_time_is_refused_on_its_line(dive, tmp_path):
    folder, lines = dive
    cols = lines[0].split(",")
    cells = lines[3].split(",")
    cells[cols.index("time")] = "1e300"
    mixed = [*lines[:3], ",".join(cells), *lines[3:7]]  # times 0, 0, 1e300, 0, 0, 12
    got = _run(tmp_path, "fast", mixed, folder / "beacons.csv", speed="10")
    # every line answered (no OverflowError, no endless wait), the bad one with an error
    assert [a["line"] for a in got] == list(range(2, len(mixed) + 1))
    assert "error" in got[2] and all("error" not in a for i, a in enumerate(got) if i != 2)


def test_a_real_pause_is_adopted_after_a_few_lines_a_glitch_is_not(dive):
    from bayes_mpem.exceptions import InputError
    from bayes_mpem.lbl.navigate.online import Navigator
    from bayes_mpem.lbl.navigate.online.navigator import GAP_CONFIRM

    folder, lines = dive
    cols = lines[0].split(",")
    rows = [dict(zip(cols, ln.split(","), strict=True)) for ln in lines[1:]]
    nav = Navigator(str(folder / "beacons.csv"), warmup=60, rng=0)
    for r in rows[:100]:
        nav.update(r)
    later = [{**r, "time": str(float(r["time"]) + 7200.0)} for r in rows[100:110]]
    for r in later[:GAP_CONFIRM]:  # the first lines after a two-hour pause: refused
        with pytest.raises(InputError, match="--max-gap"):
            nav.update(r)
    out = nav.update(later[GAP_CONFIRM])  # then the pause is adopted
    assert out.time == float(later[GAP_CONFIRM]["time"])
    assert all(nav.update(r).time == float(r["time"]) for r in later[GAP_CONFIRM + 1:])


def _spoiled(good, path, value):
    d = json.loads(json.dumps(good))
    *head, last = path
    part = d
    for k in head:
        part = part[k]
    if value is _DELETE:
        del part[last]
    else:
        part[last] = value
    return d


_DELETE = object()


def test_a_hand_edited_state_is_refused_naming_the_key_and_what_was_expected(dive, tmp_path,
                                                                              capsys):
    """Each of these edits passed the load check once, then every line was answered with an
    internal error, or answers came out impossible (p_dp = p_mp = p_ol = 0, label "dp"), and
    the broken state was saved back."""
    folder, lines = dive
    beacons = folder / "beacons.csv"
    states = {}
    for phase, n in (("online", 100), ("warmup", 30)):
        states[phase] = tmp_path / f"{phase}.json"
        _run(tmp_path, phase, lines[:n], beacons, "--state", str(states[phase]))
    good = {k: json.loads(p.read_text()) for k, p in states.items()}
    assert good["online"]["phase"] == "online" and good["warmup"]["phase"] == "warmup"
    assert good["warmup"]["buffer"] and good["warmup"]["windows"]
    bid = sorted(good["online"]["models"])[-1]
    wid = sorted(good["warmup"]["windows"])[0]
    edits = [  # (phase, key path, value, the key path and the expectation the message names)
        ("online", ["dp", "stats"], [0.5], "dp.stats has 1 numbers, expected 2"),
        ("online", ["last"], ["5000", 1.0, 2.0], "last[0] is '5000', expected time (s) in"),
        ("online", ["filter", "cov", "xx"], -100.0, "filter.cov.xx is -100.0, expected a "
                                                    "variance in (0,"),
        ("online", ["filter", "cov", "xy"], 100.0, "filter.cov is not positive definite"),
        ("online", ["filter", "x"], 1e300, "filter.x is 1e+300, expected x (m) in [-1e+07"),
        ("online", ["filter", "scale"], -1.0, "filter.scale is -1.0, expected a speed scale"),
        ("online", ["filter", "scale"], 0.0, "filter.scale is 0.0, expected a speed scale"),
        ("online", ["models", bid, "weights"], [-1.0, 1.5, 0.5],
         f"models.{bid}.weights[0] is -1.0, expected a weight in [0, 1]"),
        ("online", ["models", bid, "stats"], [0.1], f"models.{bid}.stats has 1 numbers, "
                                                    "expected 6"),
        ("online", ["models", bid], _DELETE, f"models.{bid} is missing, expected a model for "
                                             "every beacon"),
        ("online", ["windows"], {"1": "x"}, "windows is {'1': 'x'}, expected {} after the "
                                           "warm-up"),
        ("online", ["seed"], -1, "seed is -1, expected an integer >= 0"),
        ("online", ["first_time"], 1e9, "first_time is 1000000000.0, expected a time (s) no "
                                        "later than last[0]"),
        ("online", ["options", "bogus"], 1, "options.bogus is not one of its fields"),
        ("online", ["options", "alpha"], _DELETE, "options.alpha is missing"),
        ("online", ["options", "start_sd"], 1e300, "options.start_sd: expected a number in"),
        ("warmup", ["windows", wid], "x", f"windows.{wid} is 'x', expected [smallest, largest]"),
        ("warmup", ["windows", wid], [5.0, 6.0], f"windows.{wid} is [5.0, 6.0], expected"),
        ("warmup", ["buffer", 0, 2], -3.0, "buffer[0][2] is -3.0, expected range (m) in (0,"),
        ("warmup", ["first_time"], 1e9, "first_time is 1000000000.0, expected a time (s)"),
    ]
    src = tmp_path / "more.csv"
    src.write_text("\n".join([lines[0], *lines[100:110]]) + "\n")
    out = tmp_path / "o.jsonl"
    capsys.readouterr()
    for phase, path, value, expected in edits:
        d = _spoiled(good[phase], path, value)
        states[phase].write_text(json.dumps(d))
        code = main(["stream", "--beacons", str(beacons), "--replay", str(src), "--speed", "max",
                     "--state", str(states[phase]), "--out", str(out)])
        err = capsys.readouterr().err
        assert code == 2, (path, value, err)
        assert f"--state: {states[phase]}: not a valid navigator state: " in err, err
        assert expected in err, (expected, err)
        assert "Traceback" not in err and len(err) < 600, err
        assert json.loads(states[phase].read_text()) == d  # left as it was
    # the states as written load and resume
    for phase, p in states.items():
        p.write_text(json.dumps(good[phase]))
        assert main(["stream", "--beacons", str(beacons), "--replay", str(src), "--speed", "max",
                     "--state", str(p), "--out", str(out)]) == 0
        assert all("error" not in json.loads(s) for s in out.read_text().splitlines())
