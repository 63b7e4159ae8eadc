"""``bayes-mpem batch``: manifest rows checked by the command's own sub-parser (``docs/cli.md``)."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from ..batch import read_manifest, run_batch
from ..commands import COMMANDS, load
from ..exceptions import InputError
from . import survey_in
from .errors import OptionError

#: the input units' columns (their options' names), refused with the way to convert: a
#: batch's surveys are read as one-way ranges in local x, y (bayes_mpem.io.travel_time)
UNIT_OPTIONS = {"ranges", "travel_time", "sound_speed", "travel_ssp", "turnaround", "origin"}
#: options a batch sets itself (or never uses): not allowed as manifest columns
#: (``dead_reckoning`` names a file: a batch hashes only the manifest's input columns)
NOT_OPTIONS = {"help", "out", "pings", "beacons", "survey", "format", "figures", "no_figures",
               "no_progress", "palette", "dead_reckoning", "config", *UNIT_OPTIONS}
TRUE, FALSE = {"true", "yes", "1"}, {"false", "no", "0", ""}


def _argv(sub: argparse.ArgumentParser, command: str, task, options: dict) -> list:
    """Return the command line that the options of one manifest row amount to."""
    actions = {a.dest: a for a in sub._actions if a.option_strings}
    if "format" in task.inputs:
        argv = ["SURVEY", "--format", task.inputs["format"], "--out", "OUT"]
    else:
        argv = ["PINGS", "--beacons", "BEACONS", "--out", "OUT"]
    for col, cell in options.items():
        value = str(cell).strip()
        action = actions.get(col)
        if col in UNIT_OPTIONS:
            raise InputError(f"{task.where}, column {col!r}: a batch reads one-way ranges in "
                             "local x, y; convert travel times, two-way ranges or lat/lon "
                             "first (bayes_mpem.io.travel_time.convert_survey, docs/input.md)")
        if action is None or col in NOT_OPTIONS:
            known = sorted(set(actions) - NOT_OPTIONS)
            raise InputError(f"{task.where}, column {col!r}: not an option of "
                             f"'bayes-mpem {command}' in a batch; expected one of {known}")
        if action.nargs == 0:  # a flag
            if value.lower() not in TRUE | FALSE:
                raise InputError(f"{task.where}, column {col!r}: expected true or false, "
                                 f"got {value!r}")
            if value.lower() in TRUE:
                argv.append(action.option_strings[-1])
        elif value:
            argv += [action.option_strings[-1], value]
    return argv


def _quiet(kwargs: dict) -> dict:
    """Turn every ``progress`` off, nested ones too: a batch reports per survey."""
    return {k: False if k == "progress" else _quiet(v) if isinstance(v, dict) else v
            for k, v in kwargs.items()}


def tasks_from_manifest(path, command: str, subparsers: dict) -> list:
    """Return a manifest's tasks, each row's options parsed by ``subparsers[command]``.

    ``InputError`` naming the line for a cell the command would refuse.
    """
    tasks, options = read_manifest(path, command)
    sub = subparsers[command]
    sub.exit_on_error = False  # raise ArgumentError instead of exiting
    out = []
    kwargs_of = load(COMMANDS[command].batch.kwargs)
    for task, row in zip(tasks, options.to_dict("records"), strict=True):
        if "format" in task.inputs:
            try:
                fmt = survey_in.survey_format(task.inputs["survey"], task.inputs["format"])
            except OSError:
                fmt = task.inputs["format"]  # a missing file fails its task, with the reason
            task = replace(task, inputs={**task.inputs, "format": fmt})
        try:
            args = sub.parse_args(_argv(sub, command, task, row))
            kwargs = _quiet(kwargs_of(args))
        except (argparse.ArgumentError, OptionError) as exc:
            raise InputError(f"{task.where}: {exc}") from None
        out.append(replace(task, options=kwargs))
    return out


def cmd_batch(args) -> int:
    """Run ``bayes-mpem batch``: status 0 when every survey is complete, 1 when some failed."""
    tasks = tasks_from_manifest(args.manifest, args.batch_command, args.subparsers)
    result = run_batch(tasks, args.out, scheduler=args.scheduler, n_workers=args.workers,
                       progress=not args.no_progress)
    counts = result.surveys["status"].value_counts()
    print(f"{len(tasks)} surveys: {counts.get('done', 0)} done, "
          f"{counts.get('complete', 0)} already complete, {counts.get('failed', 0)} failed "
          f"({result.seconds:.1f} s)")
    for name, reason in zip(result.failures["name"], result.failures["reason"], strict=True):
        print(f"failed: {name}: {reason}", file=sys.stderr)
    print(f"wrote {args.out}/beacons.parquet, surveys.parquet, failures.parquet, classified/ "
          "and surveys/<name>/")
    return 1 if len(result.failures) else 0
