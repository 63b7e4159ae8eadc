"""The ``bayes-mpem`` command line: the parser, the dispatch and the error handling.

The sub-commands themselves live in :mod:`.lbl` (``demo``, ``simulate``,
``fit``, ``sample``, ``compare``, ``plot``, ``diagnose``), :mod:`.navigate`
(``navigate``, ``simulate --navigation``), :mod:`.stream` (``stream``) and
:mod:`.survey_in` (``locate``);
each parses nothing, calls the library and reports. Invalid input ends a
command with one ``error:`` line and exit status 2.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import warnings

from .. import __version__
from ..exceptions import InputError
from ..lbl.model.paths import PATH_CHOICES
from . import gnssa, navigate, stream
from . import options as opt
from .errors import OptionError

#: sub-command -> the module of its ``cmd_<name>`` function, imported only when the command
#: runs: building the parser loads no numpy, so ``bayes-mpem --help`` answers at once
#: (``benchmarks/bench_startup.py``).
COMMANDS: dict[str, str] = {
    **dict.fromkeys(("demo", "simulate", "fit", "plot", "sample", "compare", "diagnose"),
                    "lbl"),
    "locate": "survey_in",
    "navigate": "navigate",
    "stream": "stream",
    "batch": "batch",
}
#: the commands ``bayes-mpem batch --command`` runs: the keys of ``bayes_mpem.batch.COMMANDS``
#: (spelled out here so that building the parser imports neither pandas nor Dask; a test
#: keeps the two equal)
BATCH_COMMANDS = ("fit", "sample", "diagnose", "locate", "navigate")
#: the sub-commands that draw figures take ``--palette`` (the class colours)
FIGURE_COMMANDS = ("demo", "fit", "sample", "compare", "plot", "diagnose", "navigate", "locate")
PALETTES = ("okabe-ito", "paper")  # bayes_mpem.plots.style.PALETTES, without numpy


def _add_fit_options(p):
    p.add_argument("--method", choices=["mixture", "paper"], default="mixture",
                   help="density-mixture EM (default) or the paper's EM")
    p.add_argument("--path", choices=PATH_CHOICES, default="auto",
                   help="multipath geometry: one reflected leg, both, or per beacon the "
                        "likelier of the two (default auto)")
    p.add_argument("--sigma-dp", type=opt.positive, default=None, metavar="S",
                   help="direct-path scatter in m (default: estimated from the data)")
    p.add_argument("--pol", type=opt.probability, default=None, metavar="P",
                   help="paper EM only: outlier threshold Pol (default 0.05)")
    p.add_argument("--alpha", type=opt.fraction, default=None, metavar="A",
                   help="paper EM only: convergence factor alpha (default 0.5)")
    p.add_argument("--weights", choices=["learned", "equal"], default=None,
                   help="mixture EM only: learn the mixing weights (default) or fix them at 1/3")
    p.add_argument("--min-pings", type=opt.min_pings, default=30, metavar="N",
                   help="leave beacons with fewer replies unfitted (default 30)")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")


def _add_table_format(p):
    p.add_argument("--table-format", choices=opt.TABLE_FORMATS, default="csv",
                   help="classified.csv (default) or classified.parquet; the input table "
                        "may be either (by its extension)")


def _add_demo_plot_simulate(sub):
    p = sub.add_parser("demo", help="simulate an ABE58-like survey, fit it, write figures")
    p.add_argument("--out", default="demo-output", metavar="DIR",
                   help="output folder (default: demo-output)")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")
    p.add_argument("--no-bayes", action="store_true",
                   help="skip the Bayesian part (sampling and prior comparison: most of the "
                        "demo's ~30 s)")

    p = sub.add_parser("plot", help="draw the figures of an output folder (fit, sample, "
                                    "compare, diagnose, locate, navigate)")
    p.add_argument("result_dir", metavar="RESULT_DIR",
                   help="output folder of 'bayes-mpem fit', 'sample', 'compare', 'diagnose', "
                        "'locate' or 'navigate'")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="where to write (default: RESULT_DIR)")
    p.add_argument("--beacon", default=None, metavar="ID",
                   help="fit folders: beacon of the single-beacon figures (default: the last "
                        "one)")

    p = sub.add_parser("simulate", help="write a simulated survey (pings, beacons, truth)")
    p.add_argument("--preset", choices=["abe58", "random"], default="abe58")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")
    p.add_argument("--path", choices=["triangle", "double"], default="triangle")
    p.add_argument("--n-cycles", type=opt.at_least(1, 10**7), default=None, metavar="N",
                   help="number of ping cycles (default: the preset's)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help="hide an effect in the data, e.g. range_bias=5 (repeatable; names as "
                        "in 'bayes-mpem diagnose')")
    navigate.add_simulate_navigation(p)
    gnssa.add_simulate_gnssa(p)


def _add_fit_diagnose(sub):
    p = sub.add_parser("fit", help="fit every beacon of a survey")
    p.add_argument("pings", metavar="PINGS", help="pings CSV (time, beacon, range, x, y, depth)")
    p.add_argument("--beacons", required=True, metavar="BEACONS",
                   help="beacons CSV (beacon, x, y, depth)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--figures", action="store_true",
                   help="also write the figures (as 'bayes-mpem plot' does)")
    _add_table_format(p)
    _add_fit_options(p)

    p = sub.add_parser("diagnose", help="find which assumption the data break (bias, sound "
                                        "speed, drifts, second reflector, early outliers)")
    p.add_argument("pings", metavar="PINGS", help="pings CSV (time, beacon, range, x, y, depth)")
    p.add_argument("--beacons", required=True, metavar="BEACONS",
                   help="beacons CSV (beacon, x, y, depth)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed of the folds (default 0)")
    p.add_argument("--path", choices=PATH_CHOICES, default="auto",
                   help="multipath geometry (default: the likelier of the two)")
    p.add_argument("--effects", default=None, metavar="LIST",
                   help="comma-separated candidate effects (default: all)")
    p.add_argument("--folds", type=opt.at_least(2), default=5, metavar="K",
                   help="cross-validation folds (default 5)")
    p.add_argument("--min-gain", type=opt.non_negative, default=4.0, metavar="NATS",
                   help="minimum held-out gain to keep an effect (default 4)")
    p.add_argument("--min-pings", type=opt.min_pings, default=30, metavar="N")
    p.add_argument("--no-figures", action="store_true", help="write diagnosis.json only")
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")


def _add_locate(sub):
    p = sub.add_parser("locate", help="locate the transponders of a ranging survey (EM, and "
                                      "optionally the posterior)")
    p.add_argument("survey", metavar="SURVEY",
                   help="survey file: a deck-box log, SeaGap's obsdata.inp, GARPOS's "
                        "*-initcfg.ini or GNATSS's config.yaml")
    p.add_argument("--format", default="auto",
                   choices=["auto", "obsrange", "obsrange-sio", "obsrange-whoi", "seagap",
                            "garpos", "gnatss"],
                   help="default auto: recognised from the file; 'obsrange' detects the SIO "
                        "or WHOI variant")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--figures", action="store_true",
                   help="also write the figures (map, residuals; as 'bayes-mpem plot' does)")
    p.add_argument("--one-at-a-time", action="store_true",
                   help="SeaGap: locate each transponder on its own (its own sound speed) "
                        "instead of the array together with its centre")
    p.add_argument("--no-lag-check", action="store_true",
                   help="deck-box logs: do not test whether a lag along the track would fit "
                        "better (a few tenths of a second)")
    p.add_argument("--tat", type=opt.turn_around, default=None, metavar="S",
                   help="turn-around time in s (default: the file's, else 0.013; SeaGap 0)")
    p.add_argument("--fit-tat", action="store_true",
                   help="fit the turn-around time too (often not identifiable)")
    p.add_argument("--ci", type=opt.probability, default=0.95,
                   help="interval probability (default 0.95)")
    p.add_argument("--outliers", choices=["uniform", "first_arrival"], default="uniform",
                   help="spurious pings uniform over the window (default) or only before the "
                        "true arrival (a first-threshold-crossing detector)")
    p.add_argument("--ssp", default=None, metavar="FILE|woa09|survey|straight",
                   help="refracted rays through a sound-speed profile: a two-column file "
                        "(depth m, speed m/s), 'woa09' (the atlas at the drop point) or "
                        "'survey' (the survey's own: SeaGap's ss_prof.inp, GARPOS's svp.csv, "
                        "GNATSS's sound_speed); 'straight' for straight rays; default straight "
                        "rays, except the survey's own profile for GARPOS and GNATSS")
    p.add_argument("--speed-intervals", type=opt.at_least(0, 1000), default=None, metavar="N",
                   help="the sound speed as an unpenalised cubic B-spline in time with N "
                        "intervals (0: one speed); default: one speed for a single "
                        "transponder, and for an array (GARPOS, GNATSS, SeaGap) a smooth "
                        "spline, knots every 5 min, its smoothness chosen by the data")
    p.add_argument("--fit-lag", action="store_true",
                   help="fit a time lag of the acoustic position along the track (a position "
                        "fix logged at another moment, or a transducer ahead of the antenna)")
    p.add_argument("--sample", action="store_true",
                   help="after each EM fit, sample the posterior of the location and the ping "
                        "classes (emcee); intervals and classes from the posterior")
    p.add_argument("--walkers", type=opt.at_least(4), default=None, metavar="N",
                   help="--sample: walkers (default max(32, 2 x parameters + 2))")
    p.add_argument("--min-ess", type=opt.non_negative, default=None, metavar="N",
                   help="--sample: run until the smallest effective sample size reaches N "
                        "(default 1000)")
    p.add_argument("--seed", type=opt.seed, default=None,
                   help="--sample: random seed (default 0); same seed, same chain")
    p.add_argument("--no-progress", action="store_true",
                   help="--sample: no progress bar (terminal) or progress lines (log file)")


def _add_sample_compare(sub):
    for name, helptext in (("sample", "sample each beacon's posterior (MCMC)"),
                           ("compare", "compare equal (paper) and learned mixing priors by LOO")):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("pings", metavar="PINGS", help="pings CSV")
        p.add_argument("--beacons", required=True, metavar="BEACONS", help="beacons CSV")
        p.add_argument("--out", required=True, metavar="DIR")
        p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")
        if name == "sample":
            p.add_argument("--priors", choices=["learned", "equal"], default="learned",
                           help="Dirichlet-learned mixing weights (default) or equal 1/3")
            p.add_argument("--ci", type=opt.probability, default=0.95,
                           help="probability of the highest-density intervals (default 0.95)")
            p.add_argument("--ensembles", type=opt.at_least(1, 64), default=1, metavar="K",
                           help="independent emcee ensembles (K > 1 implies --sampler "
                                "ensemble); R-hat is reported when K > 1")
            p.add_argument("--figures", action="store_true", help="also write PNG figures")
            _add_table_format(p)
        p.add_argument("--path", choices=PATH_CHOICES, default="auto",
                       help="multipath geometry (default auto: per beacon the one the mixture "
                            "EM finds likelier)")
        p.add_argument("--sigma-dp", type=opt.positive, default=None, metavar="S",
                       help="fix sigma_DP (m) instead of sampling it")
        p.add_argument("--concentration", type=opt.positive, default=None, metavar="C",
                       help="Dirichlet concentration of the learned weights (default 1)")
        p.add_argument("--min-pings", type=opt.min_pings, default=30, metavar="N")
        p.add_argument("--sampler", choices=["auto", "independence", "ensemble"], default="auto",
                       help="independence chains from a Laplace proposal, emcee's ensemble, or "
                            "the first unless its proposal fits poorly (default auto)")
        p.add_argument("--no-progress", action="store_true",
                       help="no progress bar (terminal) or progress lines (log file)")


def _simulate_handler(args, cmd_simulate):
    """``simulate`` writes a survey, or a dive with ``--navigation``; refuse mixed options."""
    chosen = gnssa.gnssa_handler(args)  # --gnssa: a GNSS-A campaign
    if chosen is not None:
        return chosen
    if args.navigation:
        return navigate.cmd_simulate_navigation
    given = [o for o in navigate.NAVIGATION_ONLY if getattr(args, o) is not None]
    if given:
        names = ", ".join("--" + o.replace("_", "-") for o in given)

        def refuse(_args):
            raise OptionError(f"{names}: only with --navigation")

        return refuse
    return cmd_simulate


def _add_batch(sub):
    p = sub.add_parser("batch", help="run a command on every survey of a manifest (Dask)")
    p.add_argument("manifest", metavar="MANIFEST",
                   help="CSV: name, pings, beacons (or name, survey, format for locate), then "
                        "option columns named as the command's options (e.g. sigma_dp)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--command", dest="batch_command", choices=BATCH_COMMANDS, default="fit",
                   help="the command run on each survey (default fit)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running Dask scheduler (default: a local cluster)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="workers of the local cluster (default 1)")
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of ``bayes-mpem`` (exposed for the docs).

    Returns
    -------
    argparse.ArgumentParser
        With one sub-parser per command, in the order ``--help`` lists them; the
        parsed arguments carry them as ``subparsers`` (``bayes-mpem batch`` checks
        the option columns of a manifest with the command's own sub-parser).

    Examples
    --------
    >>> build_parser().parse_args(["fit", "p.csv", "--beacons", "b.csv", "--out", "o"]).method
    'mixture'
    """
    parser = argparse.ArgumentParser(
        prog="bayes-mpem",
        description="Classify acoustic ranges (direct path, multipath, outlier) and identify "
                    "each beacon's reflector.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_demo_plot_simulate(sub)
    _add_fit_diagnose(sub)
    _add_locate(sub)
    _add_sample_compare(sub)
    navigate.add_navigate(sub)
    stream.add_stream(sub)
    _add_batch(sub)
    for name in FIGURE_COMMANDS:
        sub.choices[name].add_argument(
            "--palette", choices=PALETTES, default="okabe-ito",
            help="class colours of the figures: colour-blind safe (default) or the "
                 "paper's blue, red and green")
    parser.set_defaults(subparsers=sub.choices)
    return parser


def _output_folder(args):
    """Return the folder a command writes (checked before any work), or ``None``."""
    out = getattr(args, "out", None)
    if args.command == "plot" and out is None:
        out = args.result_dir
    if out is None:
        return None
    from ..io.results import check_output_folder  # not at import: `--help` loads no numpy

    check_output_folder(out, "--out" if getattr(args, "out", None) is not None else "RESULT_DIR")
    return out


class _Failed(Exception):
    """A command returned a non-zero status: its files are not committed."""


#: commands whose non-zero status still leaves a result: a batch with failed surveys
#: writes them into ``failures.parquet`` beside the surveys that were done
_COMMITS_ON_FAILURE = frozenset({"batch"})


def _on_sigterm(signum, frame):
    # not an exception: third-party code on the stack (emcee) would print it as a traceback
    from ..io.results import abort_open_runs

    abort_open_runs()
    print("bayes-mpem: terminated; no result written", file=sys.stderr, flush=True)
    os._exit(128 + signum)


def _run(handler, args) -> int:
    """Run ``handler`` with its output folder checked first and written all or nothing."""
    out = _output_folder(args)
    if out is None:
        return handler(args)
    from ..io.results import writing

    try:
        with writing(out, extend=args.command == "plot", create=False):
            code = handler(args)
            if code and args.command not in _COMMITS_ON_FAILURE:
                raise _Failed(code)
    except _Failed as failed:
        return failed.args[0]
    return code


def _message(exc: BaseException) -> str:
    if isinstance(exc, OSError) and not isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: {exc.strerror or exc}"
    return str(exc)


def main(argv=None) -> int:
    """Entry point of ``bayes-mpem``.

    Every option is checked by the parser (an invalid value exits there, through
    :class:`SystemExit` with status 2, as argparse does); the output folder (``--out``) before any
    work; the files of a run are committed together at its end
    (:func:`bayes_mpem.io.results.writing`), so an error, Ctrl-C or ``SIGTERM``
    leaves the previous results. Invalid input or options end with one ``error:``
    line naming the file, line, column or option, and exit status 2; an unexpected
    failure with one ``internal error:`` line and status 1 (set
    ``BAYES_MPEM_TRACEBACK=1`` to see the traceback).

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 on success, 2 on invalid input, 1 on an internal error,
        128 + signal number when terminated.
    """
    args = build_parser().parse_args(argv)  # an invalid option exits here, with status 2
    import matplotlib

    matplotlib.use("Agg")  # the command line only writes files; never opens a window
    module = importlib.import_module(f"{__package__}.{COMMANDS[args.command]}")
    handler = getattr(module, f"cmd_{args.command}")
    if args.command == "simulate":
        handler = _simulate_handler(args, handler)
    colours = contextlib.nullcontext()
    # the figures' class colours, restored on return (only when figures are drawn: the
    # plotting modules import matplotlib.pyplot)
    if getattr(args, "palette", None) and getattr(args, "figures", True):
        from ..plots.style import palette_context

        colours = palette_context(args.palette)
    previous = None
    with contextlib.suppress(ValueError):  # not the main thread: no handler
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    with colours, warnings.catch_warnings():  # restores the caller's filters and showwarning
        warnings.simplefilter("default")
        # one line per warning, no source excerpt: messages for the user, not tracebacks
        warnings.showwarning = lambda msg, cat, *args, **kwargs: print(
            f"{cat.__name__}: {msg}", file=sys.stderr)
        try:
            return _run(handler, args)
        except (InputError, ValueError, OSError) as exc:
            print(f"bayes-mpem {args.command}: error: {_message(exc)}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"bayes-mpem {args.command}: interrupted; no result written", file=sys.stderr)
            return 130
        except Exception as exc:
            if os.environ.get("BAYES_MPEM_TRACEBACK"):
                raise
            print(f"bayes-mpem {args.command}: internal error: {type(exc).__name__}: {exc} "
                  "(a bug: please report it with the command; BAYES_MPEM_TRACEBACK=1 shows "
                  "where)", file=sys.stderr)
            return 1
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
