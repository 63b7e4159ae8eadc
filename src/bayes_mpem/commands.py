"""The commands of ``bayes-mpem`` in one table, every object named as text (docs/architecture.md).

Reading the table imports nothing (``bayes-mpem --help`` loads no numpy); :func:`load`
imports a ``"module:attribute"`` name on first use. Adding a command is one more entry.
"""

from __future__ import annotations

import importlib
from collections import namedtuple  # not dataclasses: `--help` would import inspect

LBL_INPUTS = ("pings", "beacons")

Batch = namedtuple("Batch", "kwargs run rows inputs files quiet", defaults=(
    "batch.commands:survey_rows", LBL_INPUTS, LBL_INPUTS, False))
Batch.__doc__ = """How ``bayes-mpem batch`` runs a command on one survey of a manifest.

Attributes
----------
kwargs : str
    The command line's builder of the library's keywords from the parsed options.
run : str
    The library call, ``run(*inputs, **options)``.
rows : str
    ``rows(result) -> (per-beacon summaries, classified table or None)``.
inputs, files : tuple of str
    The manifest's input columns, in ``run``'s order; those that are files (hashed).
quiet : bool
    ``run`` takes ``progress``, off unless given.
"""

Command = namedtuple("Command", "module options result folder figures palette units batch",
                     defaults=(None, ("summary.json", ()), None, False, False, None))
Command.__doc__ = """One sub-command of ``bayes-mpem``.

Attributes
----------
module : str
    The command-line module of its ``cmd_<name>``.
options : str
    ``options(subparsers)`` adds its sub-parser.
result : str or None
    Its result type, with ``write(folder)`` and the classmethod ``read(folder)``.
folder : tuple
    ``(file, keys)``: a folder holds this result when ``file``'s JSON object has every
    key of ``keys`` (``bayes-mpem plot``).
figures : str or None
    ``figures(result, out, *, truth=None, ...)`` draws the result, returns the paths.
palette, units : bool
    It draws figures (takes ``--palette``); it reads pings and beacons tables (takes
    the input units).
batch : Batch or None
    How ``bayes-mpem batch`` runs it, if it can.
"""


#: Every sub-command, in the order ``bayes-mpem --help`` lists them.
COMMANDS: dict[str, Command] = {
    "demo": Command("cli.lbl", "cli.parser:add_demo", palette=True),
    "plot": Command("cli.lbl", "cli.parser:add_plot", palette=True),
    "simulate": Command("cli.lbl", "cli.parser:add_simulate"),
    "fit": Command(
        "cli.lbl", "cli.parser:add_fit", "lbl.survey.fitting:SurveyFit",
        ("summary.json", ("beacons_table", "method")), "report:fit_figures",
        palette=True, units=True,
        batch=Batch("cli.lbl:fit_kwargs", "lbl.survey.fitting:fit")),
    "diagnose": Command(
        "cli.lbl", "cli.parser:add_diagnose", "lbl.diagnosis.result:Diagnosis",
        ("diagnosis.json", ()), "report:diagnosis_figures",
        palette=True, units=True,
        batch=Batch("cli.lbl:diagnose_kwargs", "lbl.diagnosis.driver:diagnose",
                    "batch.commands:diagnosis_rows", quiet=True)),
    "locate": Command(
        "cli.survey_in", "cli.parser:add_locate", "survey_in.result:SurveyInResult",
        ("summary.json", ("transponders",)), "report:locate_figures",
        palette=True,
        batch=Batch("cli.survey_in:locate_kwargs", "batch.commands:locate_file",
                    "batch.commands:locate_rows", ("survey", "format"), ("survey",))),
    "sample": Command(
        "cli.lbl", "cli.parser:add_sample", "lbl.survey.sampling:SurveyPosterior",
        ("summary.json", ("beacons_table", "priors")), "report:posterior_figures",
        palette=True, units=True,
        batch=Batch("cli.lbl:sample_command_kwargs", "lbl.survey.sampling:sample", quiet=True)),
    "compare": Command(
        "cli.lbl", "cli.parser:add_compare", "lbl.survey.comparison:SurveyComparison",
        ("compare.json", ()), "report:comparison_figures",
        palette=True, units=True),
    "navigate": Command(
        "cli.navigate", "cli.navigate:add_navigate", "lbl.navigate.result:Navigation",
        ("summary.json", ("dead_reckoning", "track", "beacons_table")), "report:navigation_figures",
        palette=True, units=True,
        batch=Batch("cli.navigate:navigate_kwargs", "lbl.navigate:navigate")),
    "stream": Command("cli.stream", "cli.stream:add_stream"),
    "batch": Command("cli.batch", "cli.parser:add_batch"),
}


def load(name: str):
    """Return the object a name of the table stands for.

    Parameters
    ----------
    name : str
        ``"module:attribute"``, the module relative to the package.

    Examples
    --------
    >>> load("commands:load") is load
    True
    """
    module, _, attribute = name.partition(":")
    return getattr(importlib.import_module(f"{__package__}.{module}"), attribute)


def with_results() -> dict:
    """Return the commands whose result ``bayes-mpem plot`` reads back, in the table's order."""
    return {name: c for name, c in COMMANDS.items() if c.result is not None}
