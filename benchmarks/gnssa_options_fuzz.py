"""An independent fuzz of the GNSS-A command-line options and their combinations.

Small valid campaigns are made first (``bayes-mpem simulate --gnssa --format garpos|gnatss
--hours 0.5``, the first 200 shots of the shipped SeaGap survey, the shipped SIO deck-box log
for the one-transponder cases). Each case runs ``bayes_mpem.cli.main([...])`` in a forked
child with a time limit and is judged:

* ``ok``: exit 0 and a complete folder: for ``locate``, ``summary.json`` and
  ``classified.csv`` with every shot of the campaign (as many rows as the run with the
  defaults); for ``simulate``, the survey file and ``truth.json``. A case whose option claims
  to change the result (``changes``) is run again without it: an identical result is an
  option silently ignored (FAIL);
* ``refused``: exit 2, one line on standard error naming the option (or the config file and
  its key; each case lists the words the message must hold), and the output folder exactly as
  before the run (absent, or the same files with the same contents);
* ``FAIL``: anything else (a traceback, another exit status, more than the time limit, an
  option silently ignored, a message not naming the option, files left behind by a refusal,
  or a verdict the case rules out).

Prints the counts and every FAIL; exits 1 on any FAIL::

    python benchmarks/gnssa_options_fuzz.py [--only SUBSTRING] [--timeout 60] [--list]
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import hashlib
import io
import json
import multiprocessing as mp
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

sys.path.insert(0, str(Path(__file__).resolve().parent))
from gnssa_fuzz import GARPOS_INI  # noqa: E402
from gnssa_fuzz import make_campaigns as array_campaigns  # noqa: E402

#: the parts of an array's summary.json that are results (the rest echoes the options)
RESULT_KEYS = ("transponders", "array_centre", "sound_speed", "residuals", "positions",
               "speed_intervals", "outliers", "ssp")


def make_campaigns(root: Path) -> dict:
    """Write the campaigns under ``root``; return ``{name: survey file}``.

    GARPOS, GNATSS and SeaGap as ``gnssa_fuzz.make_campaigns`` writes them, then the SIO
    deck-box log, a located GARPOS campaign and a profile.
    """
    from bayes_mpem.cli import main
    from bayes_mpem.io.formats import sample_file

    out = {name: folder / survey for name, (folder, survey) in array_campaigns(root).items()}
    folder = root / "sio"
    folder.mkdir()
    shutil.copy(sample_file("obsrange/SIO_CC03.txt"), folder / "SIO_CC03.txt")
    out["sio"] = folder / "SIO_CC03.txt"
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["locate", str(out["garpos"]), "--out", str(root / "result")])
    if code:
        raise SystemExit(f"locate of the garpos campaign failed ({code})")
    out["result"] = root / "result" / "summary.json"
    (root / "profile.txt").write_text("0 1530\n500 1490\n1500 1485\n3000 1500\n6000 1550\n")
    return out


# --------------------------------------------------------------------------- cases


@dataclass
class Case:
    """One command line: ``argv`` with ``{garpos}``, ``{gnatss}``, ``{seagap}``, ``{sio}``,
    ``{out}``, ``{work}`` filled in; ``expect`` the verdicts allowed; ``names`` the words a
    refusal must hold; ``changes`` the options whose removal must change an ok result;
    ``setup`` prepares the work folder (a config file, an existing output)."""

    name: str
    argv: list
    expect: tuple = ("ok", "refused")
    names: tuple = ()
    changes: tuple = ()
    setup: object = None
    timeout: float | None = None


CASES: list[Case] = []


def case(name, argv, expect=("ok", "refused"), names=(), changes=(), setup=None, timeout=None):
    CASES.append(Case(name, argv.split() if isinstance(argv, str) else argv, expect,
                      tuple(names), tuple(changes), setup, timeout))


def toml(text):
    """A setup writing ``{work}/run.toml``."""
    def fn(work: Path):
        (work / "run.toml").write_text(text)
    return fn


def existing_out(files):
    """A setup leaving an output folder with ``files`` (name: text) before the run."""
    def fn(work: Path):
        (work / "out").mkdir()
        for name, text in files.items():
            (work / "out" / name).write_text(text)
    return fn


REFUSE = ("refused",)
OK = ("ok",)
ARR = ("garpos", "gnatss")


def locate_cases():
    # --speed-intervals: an integer in [0, 1000]
    for v in ("-1", "1.5", "abc", "100000", "nan", "", "1e3"):
        case(f"speed-intervals {v!r}", f"locate {{garpos}} --out {{out}} --speed-intervals={v}",
             REFUSE, ["--speed-intervals"])
    for v in ("0", "1", "3", "1000"):
        case(f"speed-intervals {v}", f"locate {{gnatss}} --out {{out}} --speed-intervals {v}",
             OK, changes=["--speed-intervals", v])
    # --knot-minutes: (0, 1440]
    for v in ("0", "-5", "nan", "inf", "-inf", "abc", "1e9", "1441", "1e-9", "0.001", "0.05"):
        case(f"knot-minutes {v}", f"locate {{garpos}} --out {{out}} --knot-minutes={v}",
             REFUSE, ["--knot-minutes"])
    for v in ("0.1", "2.5", "10", "1440"):
        case(f"knot-minutes {v}", f"locate {{garpos}} --out {{out}} --knot-minutes {v}",
             OK, changes=["--knot-minutes", v])
    case("knot-minutes with speed-intervals",
         "locate {garpos} --out {out} --speed-intervals 4 --knot-minutes 3", REFUSE,
         ["--knot-minutes", "--speed-intervals"])
    case("knot-minutes with speed-intervals 0",
         "locate {garpos} --out {out} --speed-intervals 0 --knot-minutes 3", REFUSE,
         ["--knot-minutes", "--speed-intervals"])
    # --gradients
    for v in ("maybe", "ON", "1", "yes", ""):
        case(f"gradients {v!r}", f"locate {{garpos}} --out {{out}} --gradients={v}", REFUSE,
             ["--gradients"])
    case("gradients on", "locate {garpos} --out {out} --gradients on", OK,
         changes=["--gradients", "on"])
    case("gradients shallow", "locate {garpos} --out {out} --gradients shallow", OK,
         changes=["--gradients", "shallow"])
    case("gradients shallow, constant speed",
         "locate {garpos} --out {out} --gradients shallow --speed-intervals 0", REFUSE,
         ["--gradients", "--speed-intervals"])
    case("gradients off", "locate {garpos} --out {out} --gradients off --knot-minutes 10",
         ("ok",))
    case("gradients on, constant speed",
         "locate {garpos} --out {out} --gradients on --speed-intervals 0", REFUSE,
         ["--gradients", "--speed-intervals"])
    case("gradients off, constant speed",
         "locate {gnatss} --out {out} --gradients off --speed-intervals 0", OK)
    # --flags (GARPOS's obs.csv flag column)
    for v in ("maybe", "honor", "Honour", ""):
        case(f"flags {v!r}", f"locate {{garpos}} --out {{out}} --flags={v}", REFUSE, ["--flags"])
    case("flags reclassify, garpos", "locate {garpos} --out {out} --flags reclassify", OK)
    case("flags on a gnatss survey", "locate {gnatss} --out {out} --flags reclassify", REFUSE,
         ["--flags"])
    case("flags on a seagap survey", "locate {seagap} --out {out} --flags honour", REFUSE,
         ["--flags"])
    # --position-prior (GARPOS's site-file sigmas as priors)
    for v in ("on", "Site", "none", ""):
        case(f"position-prior {v!r}", f"locate {{garpos}} --out {{out}} --position-prior={v}",
             REFUSE, ["--position-prior"])
    case("position-prior off, garpos", "locate {garpos} --out {out} --position-prior off", OK,
         changes=["--position-prior", "off"])
    case("position-prior site, garpos", "locate {garpos} --out {out} --position-prior site", OK)
    case("position-prior on a gnatss survey", "locate {gnatss} --out {out} --position-prior "
         "site", REFUSE, ["--position-prior"])
    case("position-prior on a seagap survey", "locate {seagap} --out {out} --position-prior "
         "off", REFUSE, ["--position-prior"])
    case("sample with --position-prior off", "locate {garpos} --out {out} --sample --min-ess 50 "
         "--no-progress --position-prior off", OK, timeout=120)
    # --ssp
    case("ssp missing file", "locate {garpos} --out {out} --ssp {work}/nope.txt", REFUSE,
         ["nope.txt"])
    case("ssp a folder", "locate {garpos} --out {out} --ssp {work}", REFUSE, ["profile"])
    case("ssp empty text", ["locate", "{garpos}", "--out", "{out}", "--ssp", ""], REFUSE,
         ["--ssp"])
    case("ssp bad file", "locate {garpos} --out {out} --ssp {work}/bad.txt", REFUSE,
         ["bad.txt"], setup=lambda w: (w / "bad.txt").write_text("depth speed\nabc 1500\n"))
    case("ssp the survey file itself", "locate {garpos} --out {out} --ssp {garpos}", REFUSE,
         [GARPOS_INI])
    case("ssp straight", "locate {garpos} --out {out} --ssp straight", OK,
         changes=["--ssp", "straight"])
    case("ssp file", "locate {gnatss} --out {out} --ssp {root}/profile.txt", OK,
         changes=["--ssp", "{root}/profile.txt"])
    case("ssp STRAIGHT", "locate {garpos} --out {out} --ssp STRAIGHT", REFUSE, ["STRAIGHT"])
    # --ci
    for v in ("0", "1", "95", "nan", "-0.5", "abc", "inf"):
        case(f"ci {v}", f"locate {{garpos}} --out {{out}} --ci={v}", REFUSE, ["--ci"])
    case("ci 0.68", "locate {garpos} --out {out} --ci 0.68", OK, changes=["--ci", "0.68"])
    case("ci 1e-9", "locate {garpos} --out {out} --ci 1e-9", OK)
    # --outliers
    case("outliers bad", "locate {garpos} --out {out} --outliers gaussian", REFUSE,
         ["--outliers"])
    case("outliers first_arrival", "locate {gnatss} --out {out} --outliers first_arrival", OK,
         changes=["--outliers", "first_arrival"])
    # sampler options
    for opt_, vals in (("--walkers", ("1", "3", "0", "abc", "-4", "1e3", "100000")),
                       ("--min-ess", ("-1", "nan", "inf", "abc", "1e12", "640001")),
                       ("--seed", ("-1", "abc", "1.5", "nan"))):
        for v in vals:
            case(f"sample {opt_} {v}",
                 f"locate {{garpos}} --out {{out}} --sample --min-ess 50 {opt_}={v}",
                 REFUSE, [opt_])
    for opt_, v in (("--walkers", "8"), ("--min-ess", "50"), ("--seed", "3"),
                    ("--no-progress", None)):
        argv = f"locate {{garpos}} --out {{out}} {opt_}" + (f" {v}" if v else "")
        case(f"{opt_} without --sample", argv, REFUSE, [opt_, "--sample"])
    case("sample seed 2**70", f"locate {{garpos}} --out {{out}} --sample --min-ess 50 "
         f"--no-progress --seed {2**70}", ("ok", "refused"), ["--seed"], timeout=120)
    case("sample walkers 4 (too few for an array)", "locate {garpos} --out {out} --sample "
         "--min-ess 50 --no-progress --walkers 4", ("ok", "refused"), ["--walkers"],
         timeout=120)
    case("sample min-ess 0", "locate {garpos} --out {out} --sample --min-ess 0 --no-progress",
         ("ok", "refused"), ["--min-ess"], timeout=120)
    for extra in ("--speed-intervals 0", "--knot-minutes 10",
                  "--outliers first_arrival", "--ssp straight"):
        case(f"sample with {extra}", f"locate {{gnatss}} --out {{out}} --sample --min-ess 50 "
             f"--no-progress {extra}", OK, timeout=120)
    # a 0.5-h campaign: the gate leaves the gradients out, so their posterior is all but flat
    # (did not converge: R-hat 2.2 after 10,700 steps, 2.4 GB, stopped at 400 s)
    case("sample with --gradients on (0.5 h)", "locate {gnatss} --out {out} --sample "
         "--min-ess 50 --no-progress --gradients on", REFUSE, ["--gradients", "--sample"],
         timeout=120)
    case("sample with --gradients shallow (0.5 h)", "locate {gnatss} --out {out} --sample "
         "--min-ess 50 --no-progress --gradients shallow", REFUSE, ["--gradients", "--sample"],
         timeout=120)
    case("sample with --flags reclassify", "locate {garpos} --out {out} --sample --min-ess 50 "
         "--no-progress --flags reclassify", OK, timeout=120)
    case("sample seagap array", "locate {seagap} --out {out} --sample --min-ess 50 "
         "--no-progress", OK, timeout=120)
    case("sample seagap one at a time", "locate {seagap} --out {out} --sample --min-ess 50 "
         "--no-progress --one-at-a-time", OK, timeout=120)
    case("ssp survey on a deck-box log", "locate {sio} --out {out} --ssp survey", REFUSE,
         ["ssp"])
    case("ssp woa09 on gnatss", "locate {gnatss} --out {out} --ssp woa09", OK,
         changes=["--ssp", "woa09"])
    case("straight rays with gradients", "locate {garpos} --out {out} --ssp straight "
         "--gradients on", ("ok", "refused"), ["--gradients"])
    case("sample ci 0.5", "locate {garpos} --out {out} --sample --min-ess 50 --no-progress "
         "--ci 0.5", OK, timeout=120)
    # one-transponder options on an array
    for extra in ("--tat 0.1", "--fit-tat", "--fit-lag", "--one-at-a-time", "--no-lag-check",
                  "--tat 0"):
        for camp in ARR:
            case(f"{extra} on {camp}", f"locate {{{camp}}} --out {{out}} {extra}", REFUSE,
                 [extra.split()[0]])
    case("--no-lag-check on a seagap array", "locate {seagap} --out {out} --no-lag-check",
         REFUSE, ["--no-lag-check"])
    case("--fit-tat on a seagap array", "locate {seagap} --out {out} --fit-tat", REFUSE,
         ["--fit-tat", "--one-at-a-time"])
    case("seagap one at a time", "locate {seagap} --out {out} --one-at-a-time", OK)
    case("seagap one at a time with knot-minutes",
         "locate {seagap} --out {out} --one-at-a-time --knot-minutes 3", REFUSE,
         ["--knot-minutes"])
    case("seagap one at a time with gradients",
         "locate {seagap} --out {out} --one-at-a-time --gradients on", REFUSE, ["--gradients"])
    case("seagap one at a time with the shallow gradient",
         "locate {seagap} --out {out} --one-at-a-time --gradients shallow", REFUSE,
         ["--gradients"])
    case("seagap array", "locate {seagap} --out {out} --knot-minutes 10", OK,
         changes=["--knot-minutes", "10"])
    # array options on a one-transponder deck-box log
    for extra in ("--gradients on", "--knot-minutes 5", "--flags honour",
                  "--gradients auto", "--gradients shallow", "--position-prior site"):
        case(f"{extra} on a deck-box log", f"locate {{sio}} --out {{out}} {extra}", REFUSE,
             [extra.split()[0]])
    case("--one-at-a-time on a deck-box log", "locate {sio} --out {out} --one-at-a-time",
         REFUSE, ["--one-at-a-time"])
    # --format
    for fmt, camp in (("gnatss", "garpos"), ("garpos", "gnatss"), ("seagap", "garpos"),
                      ("obsrange", "garpos"), ("garpos", "sio")):
        case(f"--format {fmt} on {camp}", f"locate {{{camp}}} --out {{out}} --format {fmt}",
             REFUSE, ["--format"])
    case("--format GARPOS", "locate {garpos} --out {out} --format GARPOS", REFUSE, ["--format"])
    # options of other commands
    for extra in ("--sigma-dp 2", "--beacons b.csv", "--path double", "--priors equal",
                  "--draws 100", "--hours 2", "--track circle", "--gnssa", "--palette paper",
                  "--table-format parquet", "--effect range_bias=5", "--travel-time",
                  "--method paper", "--knots 5"):
        case(f"other command's {extra}", f"locate {{garpos}} --out {{out}} {extra}", REFUSE,
             [extra.split()[0]])
    # argparse's unique prefixes are the options they abbreviate (not dropped)
    case("abbreviated --gradient on", "locate {garpos} --out {out} --gradient on", OK,
         changes=["--gradient", "on"])
    case("abbreviated --speed-interval 3", "locate {garpos} --out {out} --speed-interval 3",
         OK, changes=["--speed-interval", "3"])
    case("ambiguous --s 3", "locate {garpos} --out {out} --s 3", REFUSE, ["--s"])
    case("abbreviation repeating", "locate {garpos} --out {out} --knot-minutes 5 --knot 10",
         REFUSE, ["--knot"])
    # repeated options
    case("ci twice, different", "locate {garpos} --out {out} --ci 0.9 --ci 0.5", REFUSE,
         ["--ci"])
    case("ci twice, same", "locate {garpos} --out {out} --ci 0.9 --ci 0.9", OK)
    case("gradients twice", "locate {garpos} --out {out} --gradients on --gradients off",
         REFUSE, ["--gradients"])
    case("knot-minutes twice", "locate {garpos} --out {out} --knot-minutes 5 --knot-minutes=10",
         REFUSE, ["--knot-minutes"])
    case("out twice", "locate {garpos} --out {out} --out {work}/other", REFUSE, ["--out"])
    case("figures twice", "locate {garpos} --out {out} --figures --fig", OK, timeout=120)
    case("two surveys", "locate {garpos} {gnatss} --out {out}", REFUSE, [])
    # --out
    case("out an existing file", "locate {garpos} --out {work}/file.txt", REFUSE, ["--out"],
         setup=lambda w: (w / "file.txt").write_text("keep me\n"))
    case("out under a file", "locate {garpos} --out {work}/file.txt/sub", REFUSE, ["--out"],
         setup=lambda w: (w / "file.txt").write_text("keep me\n"))
    case("out unwritable", "locate {garpos} --out /proc/bayes-mpem-out", REFUSE, ["--out"])
    case("out empty", ["locate", "{garpos}", "--out", ""], REFUSE, ["--out"])
    case("out the survey's folder", "locate {garpos} --out {garpos_dir}", REFUSE, ["--out"])
    case("out the gnatss survey's folder", "locate {gnatss} --out {gnatss_dir}", REFUSE,
         ["--out"])
    case("out an earlier result", "locate {garpos} --out {out}", OK,
         setup=existing_out({"summary.json": "{}", "classified.csv": "line\n"}))
    case("out missing", "locate {garpos}", REFUSE, ["--out"])
    case("survey a folder", "locate {garpos_dir} --out {out}", REFUSE, [])
    # --config
    cfg = "locate {garpos} --out {out} --config {work}/run.toml"
    for label, text, words in (
            ("wrong type", "knot_minutes = 'fast'\n", ["knot_minutes"]),
            ("nan", "knot_minutes = nan\n", ["knot_minutes"]),
            ("negative intervals", "speed_intervals = -3\n", ["speed_intervals"]),
            ("float intervals", "speed_intervals = 2.5\n", ["speed_intervals"]),
            ("bool gradients", "gradients = true\n", ["gradients"]),
            ("bad gradients", "gradients = 'maybe'\n", ["gradients"]),
            ("unknown key", "knot_minute = 5\n", ["knot_minute"]),
            ("other command's key", "sigma_dp = 2.0\n", ["sigma_dp"]),
            ("simulate's key", "hours = 2.0\n", ["hours"]),
            ("a table", "[locate]\nci = 0.9\n", ["locate"]),
            ("a list", "ci = [0.9, 0.5]\n", ["ci"]),
            ("flag as text", "sample = 'yes'\n", ["sample"]),
            ("config in the file", "config = 'other.toml'\n", ["config"]),
            ("not toml", "ci: 0.9\n", ["run.toml"]),
            ("seed without sample", "seed = 3\n", ["--seed"]),
            ("tat on an array", "tat = 0.1\n", ["--tat"]),
            ("knot with intervals", "knot_minutes = 3\nspeed_intervals = 4\n",
             ["--knot-minutes"]),
            ("key twice", "ci = 0.9\nci = 0.5\n", ["run.toml"]),
            ("empty string", "ssp = ''\n", ["ssp"])):
        case(f"config {label}", cfg, REFUSE, ["run.toml", *words], setup=toml(text))
    case("config ok", cfg, OK, setup=toml("knot_minutes = 10\nci = 0.68\n"))
    case("config out, overridden by the command line", cfg, OK,
         setup=toml("out = '/proc/x'\n"))
    case("palette without figures", "locate {garpos} --out {out} --palette paper", REFUSE,
         ["--palette"])
    case("palette with figures", "locate {garpos} --out {out} --palette paper --figures", OK,
         timeout=120)
    case("config overridden", cfg + " --ci 0.9", OK, setup=toml("ci = 0.68\n"))
    case("config missing", "locate {garpos} --out {out} --config {work}/none.toml", REFUSE,
         ["none.toml"])
    case("config a folder", "locate {garpos} --out {out} --config {work}", REFUSE, ["--config"])
    case("config twice", "locate {garpos} --out {out} --config {work}/run.toml "
         "--config {work}/b.toml", REFUSE, ["--config"],
         setup=lambda w: ((w / "run.toml").write_text("ci = 0.5\n"),
                          (w / "b.toml").write_text("ci = 0.9\n")))


def simulate_cases():
    for v in ("0", "-1", "1e6", "nan", "inf", "abc", "48.5"):
        case(f"simulate hours {v}", f"simulate --gnssa --out {{out}} --hours={v}", REFUSE,
             ["--hours"])
    case("simulate hours 0.01", "simulate --gnssa --out {out} --hours 0.01",
         ("ok", "refused"), ["--hours"])
    case("simulate hours 0.2 station", "simulate --gnssa --out {out} --hours 0.2 "
         "--track station", OK)
    for v in ("spiral", "Circle", ""):
        case(f"simulate track {v!r}", f"simulate --gnssa --out {{out}} --track={v}", REFUSE,
             ["--track"])
    for extra in ("--format garpos", "--gradients", "--no-gradients", "--hours 1",
                  "--track circle"):
        # --no-gradients is named as --gradients, the one option (its negation)
        case(f"simulate {extra} without --gnssa", f"simulate --out {{out}} {extra}", REFUSE,
             [extra.split()[0].replace("--no-", "--"), "--gnssa"])
    for extra in ("--preset random", "--path double", "--n-cycles 10",
                  "--effect range_bias=5", "--navigation"):
        case(f"simulate --gnssa {extra}", f"simulate --gnssa --hours 0.2 --out {{out}} {extra}",
             REFUSE, [extra.split()[0]])
    case("simulate --preset abe58 --gnssa (the default, given)",
         "simulate --gnssa --hours 0.2 --preset abe58 --out {out}", ("ok", "refused"),
         ["--preset"])
    for v in ("-1", "abc", "1.5", "nan"):
        case(f"simulate seed {v}", f"simulate --gnssa --hours 0.2 --out {{out}} --seed={v}",
             REFUSE, ["--seed"])
    case("simulate seed 2**70", f"simulate --gnssa --hours 0.2 --out {{out}} --seed {2**70}",
         ("ok", "refused"), ["--seed"])
    case("simulate format bad", "simulate --gnssa --hours 0.2 --out {out} --format seagap",
         REFUSE, ["--format"])
    case("simulate gradients twice", "simulate --gnssa --hours 0.2 --out {out} --gradients "
         "--no-gradients", REFUSE, ["--gradients"])
    case("simulate hours twice", "simulate --gnssa --out {out} --hours 0.2 --hours 3",
         REFUSE, ["--hours"])
    case("simulate out a file", "simulate --gnssa --hours 0.2 --out {work}/file.txt", REFUSE,
         ["--out"], setup=lambda w: (w / "file.txt").write_text("keep me\n"))
    case("simulate config bad", "simulate --gnssa --out {out} --config {work}/run.toml",
         REFUSE, ["run.toml", "hours"], setup=toml("hours = -2\n"))
    case("simulate config locate's key", "simulate --gnssa --out {out} --config "
         "{work}/run.toml", REFUSE, ["run.toml", "knot_minutes"],
         setup=toml("knot_minutes = 5\n"))
    case("simulate config gnssa", "simulate --out {out} --hours 0.2 --config {work}/run.toml",
         OK, setup=toml("gnssa = true\nformat = 'gnatss'\ntrack = 'circle'\n"))


def plot_cases():
    case("plot beacon on a locate folder", "plot {result_dir} --out {out} --beacon M01",
         REFUSE, ["--beacon"])
    case("plot palette", "plot {result_dir} --out {out} --palette paper", OK, timeout=120)
    case("plot palette bad", "plot {result_dir} --out {out} --palette viridis", REFUSE,
         ["--palette"])
    case("plot out a file", "plot {result_dir} --out {work}/file.txt", REFUSE, ["--out"],
         setup=lambda w: (w / "file.txt").write_text("keep me\n"))
    case("plot a campaign folder", "plot {garpos_dir} --out {out}", REFUSE, [])
    case("plot locate's option", "plot {result_dir} --out {out} --knot-minutes 5", REFUSE,
         ["--knot-minutes"])
    case("plot twice out", "plot {result_dir} --out {out} --out {work}/b", REFUSE, ["--out"])


def batch_manifest(rows):
    """A setup writing ``{work}/m.csv`` (``{garpos}`` etc. filled in by the runner)."""
    def fn(work: Path, paths: dict):
        header = sorted({k for r in rows for k in r})
        lines = [",".join(["name", "survey", "format", *header])]
        for i, r in enumerate(rows):
            cells = [str(r.get(k, "")) for k in header]
            lines.append(",".join([f"s{i}", "{garpos}", "garpos", *cells]))
        (work / "m.csv").write_text("\n".join(lines).format(**paths) + "\n")
    fn.batch = True
    return fn


def batch_cases():
    argv = "batch {work}/m.csv --command locate --out {out} --no-progress"
    for col, v in (("knot_minutes", "0"), ("knot_minutes", "nan"), ("gradients", "maybe"),
                   ("speed_intervals", "1.5"), ("ci", "95"), ("tat", "0.1"),
                   ("flags", "maybe"), ("position_prior", "on"), ("sample", "perhaps"),
                   ("walkers", "2"),
                   ("seed", "4"), ("one_at_a_time", "true"), ("sigma_dp", "3")):
        case(f"batch {col}={v}", argv, REFUSE, ["m.csv", col],
             setup=batch_manifest([{col: v}]))
    case("batch knot with intervals", argv, REFUSE, ["m.csv", "knot"],
         setup=batch_manifest([{"knot_minutes": "3", "speed_intervals": "4"}]))
    case("batch fine", argv, OK, setup=batch_manifest([{"knot_minutes": "10"}]), timeout=120)


# --------------------------------------------------------------------------- running


def run_child(argv, conn):
    """Run the command line in this (forked) process; send back status, stderr, stdout."""
    from bayes_mpem.cli import main

    err, out = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 2
    except BaseException:  # noqa: BLE001 - the verdict reports it
        import traceback

        err.write("Traceback (escaped main):\n" + traceback.format_exc())
        code = -1
    conn.send((code, err.getvalue(), out.getvalue()))
    conn.close()


def run(argv, timeout):
    """Run ``main(argv)`` in a forked child; return ``(code, stderr, stdout)`` or None."""
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=run_child, args=(argv, send))
    proc.start()
    send.close()
    if not recv.poll(timeout):
        proc.kill()
        proc.join()
        return None
    try:
        got = recv.recv()
    except EOFError:
        got = (f"died {proc.exitcode}", "", "")
    proc.join()
    return got


def snapshot(path: Path) -> dict:
    """Every file under ``path`` with its contents' hash (``{}`` for a missing path)."""
    if not path.exists():
        return {}
    if path.is_file():
        return {".": hashlib.sha1(path.read_bytes()).hexdigest()}
    return {str(p.relative_to(path)): hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(path.rglob("*")) if p.is_file()}


def fill(argv, paths):
    return [a.format(**paths) for a in argv]


def result_part(summary: dict) -> str:
    return json.dumps({k: summary.get(k) for k in RESULT_KEYS}, sort_keys=True)


def judge_ok(c: Case, argv, out: Path, stdout: str, paths, timeout, rows):
    """Exit 0: a complete folder with every shot; an option that changes nothing is a FAIL."""
    command = argv[0]
    if command == "simulate":
        names = {p.name for p in out.iterdir()} if out.is_dir() else set()
        if "truth.json" not in names or not any(n.endswith((".ini", ".yaml")) for n in names):
            return "FAIL", f"exit 0 without the campaign and truth.json: {sorted(names)}"
        return "ok", f"{len(names)} files"
    if command == "plot":
        pngs = list(out.glob("*.png")) if out.is_dir() else []
        return ("ok", f"{len(pngs)} figures") if pngs else ("FAIL", "exit 0 without figures")
    if command == "batch":
        if not (out / "surveys.parquet").is_file():
            return "FAIL", "exit 0 without surveys.parquet"
        return "ok", "batch complete"
    for name in ("summary.json", "classified.csv"):
        if not (out / name).is_file():
            return "FAIL", f"exit 0 without {name}"
    summary = json.loads((out / "summary.json").read_text())
    with open(out / "classified.csv", newline="") as fh:
        n = sum(1 for _ in csv.DictReader(fh))
    survey = argv[1]
    want = rows.get(survey)
    if want is not None and n != want:
        return "FAIL", f"{n} rows in classified.csv, {want} with the defaults: shots lost"
    if c.changes:
        base = list(argv)
        i = base.index(c.changes[0])
        del base[i:i + len(c.changes)]
        other = out.parent / "out-without"
        shutil.rmtree(other, ignore_errors=True)
        base[base.index(str(out))] = str(other)
        got = run(base, timeout)
        if got is None or got[0] != 0:
            return "FAIL", f"the run without {' '.join(c.changes)} did not finish: {got}"
        ref = json.loads((other / "summary.json").read_text())
        if result_part(ref) == result_part(summary):
            return "FAIL", f"{' '.join(c.changes)}: the same result as without it (ignored)"
    return "ok", f"{n} rows"


def said(word: str, message: str) -> bool:
    """Whether ``message`` names ``word``: an option and its key (``--knot-minutes``,
    ``knot_minutes``) name one thing."""
    def norm(t):
        return t.lower().replace("-", "_")
    w = norm(word)
    return w in norm(message) or w.lstrip("_") in norm(message)


def judge_refused(c: Case, err: str, before: dict, out: Path):
    """Exit 2: one line naming the option (or file and key); the output folder untouched."""
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    last = lines[-1] if lines else ""
    if "error" not in last:
        return "FAIL", f"exit 2 without an error line: {err.strip()[-300:]!r}"
    missing = [w for w in c.names if not said(w, last)]
    if missing:
        return "FAIL", f"the message does not name {missing}: {last[:300]}"
    after = snapshot(out)
    if after != before:
        return "FAIL", f"the output folder changed on refusal: {sorted(set(after) ^ set(before))}"
    return "refused", last[:160]


def run_case(c: Case, paths: dict, work: Path, timeout: float, rows: dict):
    """Run one case; return ``(verdict, detail, seconds)``."""
    work.mkdir(parents=True)
    local = {**paths, "work": str(work), "out": str(work / "out")}
    if c.setup is not None:
        if getattr(c.setup, "batch", False):
            c.setup(work, local)
        else:
            c.setup(work)
    argv = fill(c.argv, local)
    out = Path(local["out"])
    watched = {Path(a) for i, a in enumerate(argv) if i and argv[i - 1] == "--out"} or {out}
    before = {p: snapshot(p) for p in watched}
    inputs = {k: snapshot(Path(v)) for k, v in paths.items() if k.endswith("_dir")}
    limit = c.timeout or timeout
    t0 = time.perf_counter()
    got = run(argv, limit)
    secs = time.perf_counter() - t0
    if got is None:
        return "FAIL", f"no answer within {limit:g} s", secs
    code, err, stdout = got
    if "Traceback" in err:
        return "FAIL", "traceback: " + err.strip().splitlines()[-1][:300], secs
    changed = [k for k, v in inputs.items() if snapshot(Path(paths[k])) != v]
    if code == 0:
        outs = [Path(a) for i, a in enumerate(argv) if i and argv[i - 1] == "--out"]
        verdict, detail = judge_ok(c, argv, outs[-1] if outs else out, stdout, local, limit,
                                   rows)
    elif code == 2:
        verdict, detail = "refused", ""
        for p in watched:
            verdict, detail = judge_refused(c, err, before[p], p)
            if verdict == "FAIL":
                break
    else:
        return "FAIL", f"exit {code}: {err.strip()[-300:]}", secs
    if changed and verdict != "FAIL":
        verdict, detail = "FAIL", f"an input folder changed: {changed}"
    if verdict != "FAIL" and verdict not in c.expect:
        msg = (err.strip().splitlines() or [""])[-1]
        return "FAIL", f"{verdict}, expected {'/'.join(c.expect)}: {msg[:300]}", secs
    return verdict, detail, secs


def baseline_rows(paths: dict, work: Path, timeout: float) -> dict:
    """The rows of ``classified.csv`` with the defaults, per campaign."""
    rows = {}
    for key in ("garpos", "gnatss", "seagap", "sio"):  # not "result": a locate output
        out = work / f"base-{key}"
        got = run(["locate", paths[key], "--out", str(out)], timeout)
        if got is None or got[0] != 0:
            raise SystemExit(f"the {key} campaign does not locate with the defaults: {got}")
        with open(out / "classified.csv", newline="") as fh:
            rows[paths[key]] = sum(1 for _ in csv.DictReader(fh))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", default=None, help="run the cases whose name holds this")
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args(argv)
    locate_cases()
    simulate_cases()
    plot_cases()
    batch_cases()
    cases = [c for c in CASES if a.only is None or a.only in c.name]
    if a.list:
        print("\n".join(c.name for c in cases))
        return 0
    t0 = time.perf_counter()
    counts: dict = {}
    fails = []
    with tempfile.TemporaryDirectory(prefix="gnssa-opts-") as tmp:
        root = Path(tmp)
        camp = make_campaigns(root / "campaigns")
        paths = {k: str(v) for k, v in camp.items()}
        paths.update({f"{k}_dir": str(v.parent) for k, v in camp.items()})
        paths["root"] = str(root / "campaigns")
        rows = baseline_rows(paths, root / "base", a.timeout)
        for i, c in enumerate(cases):
            verdict, detail, secs = run_case(c, paths, root / f"case{i:03d}", a.timeout, rows)
            counts[verdict] = counts.get(verdict, 0) + 1
            if verdict == "FAIL":
                fails.append((c.name, detail))
                print(f"FAIL {c.name}: {detail}", flush=True)
            elif os.environ.get("FUZZ_VERBOSE"):
                print(f"{verdict:8s} {c.name}: {detail}", flush=True)
            shutil.rmtree(root / f"case{i:03d}", ignore_errors=True)
    print(f"{len(cases)} cases in {time.perf_counter() - t0:.0f} s: "
          + ", ".join(f"{counts.get(k, 0)} {k}" for k in ("ok", "refused", "FAIL")))
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
