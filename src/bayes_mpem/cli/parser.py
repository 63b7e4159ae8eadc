"""The ``bayes-mpem`` parser, dispatch and error handling (the commands: ``commands.COMMANDS``)."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import warnings

from .. import __version__
from ..commands import COMMANDS, load, with_results
from ..exceptions import InputError, Interrupted
from ..lbl.model.paths import PATH_CHOICES
from . import gnssa, navigate
from . import options as opt

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


def add_demo(sub):
    """Add ``demo``'s sub-parser."""
    p = sub.add_parser("demo", help="simulate an ABE58-like survey, fit it, write figures")
    p.add_argument("--out", default="demo-output", metavar="DIR",
                   help="output folder (default: demo-output)")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")
    p.add_argument("--no-bayes", action="store_true",
                   help="skip the Bayesian part (sampling and prior comparison): about 4 s "
                        "instead of the demo's 16 s")


def add_plot(sub):
    """Add ``plot``'s sub-parser."""
    kinds = list(with_results())
    p = sub.add_parser("plot", help=f"draw the figures of an output folder ({', '.join(kinds)})")
    p.add_argument("result_dir", metavar="RESULT_DIR",
                   help="output folder of 'bayes-mpem " + "', '".join(kinds[:-1])
                        + f"' or '{kinds[-1]}'")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="where to write (default: RESULT_DIR)")
    p.add_argument("--beacon", default=None, metavar="ID",
                   help="fit folders: beacon of the single-beacon figures (default: the last "
                        "one)")


def add_simulate(sub):
    """Add ``simulate``'s sub-parser."""
    p = sub.add_parser("simulate", help="write a simulated survey (pings, beacons, truth)")
    # --preset and --path default to None (abe58, triangle): --gnssa refuses them when given
    p.add_argument("--preset", choices=["abe58", "random"], default=None,
                   help="the survey's geometry (default abe58)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")
    p.add_argument("--path", choices=["triangle", "double"], default=None,
                   help="the multipath geometry (default triangle)")
    p.add_argument("--n-cycles", type=opt.at_least(1, 10**7), default=None, metavar="N",
                   help="number of ping cycles (default: the preset's)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help="hide an effect in the data, e.g. range_bias=5 (repeatable; names as "
                        "in 'bayes-mpem diagnose')")
    navigate.add_simulate_navigation(p)
    gnssa.add_simulate_gnssa(p)


def add_fit(sub):
    """Add ``fit``'s sub-parser."""
    p = sub.add_parser("fit", help="fit every beacon of a survey")
    p.add_argument("pings", metavar="PINGS", help="pings CSV (time, beacon, range, x, y, depth)")
    p.add_argument("--beacons", required=True, metavar="BEACONS",
                   help="beacons CSV (beacon, x, y, depth)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--figures", action="store_true",
                   help="also write the figures (as 'bayes-mpem plot' does)")
    _add_table_format(p)
    _add_fit_options(p)


def add_diagnose(sub):
    """Add ``diagnose``'s sub-parser."""
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


def add_locate(sub):
    """Add ``locate``'s sub-parser."""
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
    p.add_argument("--knot-minutes", type=opt.knot_minutes,
                   default=None, metavar="M",
                   help="array surveys: the smooth sound speed's knot spacing (default 5)")
    p.add_argument("--gradients", choices=["auto", "on", "shallow", "off"], default=None,
                   help="array surveys: horizontal sound-speed gradients (GARPOS's shallow and "
                        "deep terms; on: both, shallow: the shallow one only); default auto: "
                        "fitted where the track constrains them, the deep one only where "
                        "shots pass over the array, the reason recorded and printed")
    p.add_argument("--correlation", type=opt.correlation, default=None,
                   metavar="auto|off|MU_T[,MU_MT[,WHITE]]",
                   help="array surveys: the replies' noise correlated in time (MU_T, s) and "
                        "across transponders (MU_MT, default 0.5), GARPOS's data covariance, "
                        "with a share WHITE of independent noise (default 0); default auto: "
                        "chosen by likelihood, independent replies among the choices, "
                        "recorded and printed")
    p.add_argument("--flags", choices=["honour", "reclassify"], default=None,
                   help="GARPOS surveys: shots flagged in obs.csv are left out of the fit "
                        "(honour, the default) or fitted and classified with the others")
    p.add_argument("--position-prior", choices=["auto", "site", "off"], default=None,
                   help="GARPOS surveys: the site file's sigmas above 0 as Gaussian priors on "
                        "the positions and the array's shift, as GARPOS uses them (site), the "
                        "same but scaled up where the fit moved the positions farther than "
                        "they allow (auto, the default), or every coordinate not held free "
                        "(off)")
    p.add_argument("--fit-lag", action="store_true",
                   help="fit a time lag of the acoustic position along the track (a position "
                        "fix logged at another moment, or a transducer ahead of the antenna)")
    p.add_argument("--sample", action="store_true",
                   help="after each EM fit, sample the posterior of the location and the ping "
                        "classes (emcee); intervals and classes from the posterior")
    p.add_argument("--walkers", type=opt.at_least(4, 4096), default=None, metavar="N",
                   help="--sample: walkers, at most 4096 as for 'sample' (default max(32, 2 x "
                        "parameters + 2))")
    p.add_argument("--min-ess", type=opt.non_negative, default=None, metavar="N",
                   help="--sample: run until the smallest effective sample size reaches N "
                        "(default 1000)")
    p.add_argument("--seed", type=opt.seed, default=None,
                   help="--sample: random seed (default 0); same seed, same chain")
    p.add_argument("--no-progress", action="store_true",
                   help="--sample: no progress bar (terminal) or progress lines (log file)")


def add_sample(sub):
    """Add ``sample``'s sub-parser."""
    _add_posterior(sub, "sample", "sample each beacon's posterior (MCMC)")


def add_compare(sub):
    """Add ``compare``'s sub-parser."""
    _add_posterior(sub, "compare", "compare equal (paper) and learned mixing priors by LOO")


def _add_posterior(sub, name, helptext):
    p = sub.add_parser(name, help=helptext)
    p.add_argument("pings", metavar="PINGS", help="pings CSV")
    p.add_argument("--beacons", required=True, metavar="BEACONS", help="beacons CSV")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")
    if name == "sample":
        p.add_argument("--priors", choices=["learned", "equal"], default="learned",
                       help="Dirichlet-learned mixing weights (default) or equal 1/3")
        p.add_argument("--ci", type=opt.sampled_probability, default=0.95,
                       help="probability of the highest-density intervals, in [0.5, 1) "
                            "(default 0.95)")
        p.add_argument("--ensembles", type=opt.at_least(1, 64), default=None, metavar="K",
                       help="independent emcee ensembles of differential evolution "
                            "(default 2; K > 1 implies --sampler ensemble); R-hat "
                            "compares them")
        p.add_argument("--log-likelihood", action=argparse.BooleanOptionalAction,
                       default=False,
                       help="keep each range's log-likelihood at every draw in "
                            "posterior_<id>.nc (for LOO; default: not kept)")
        p.add_argument("--predictive", action="store_true",
                       help="also write posterior predictive ranges (one per ping and draw)")
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
                   help="emcee's moves: an independence proposal (Laplace Student-t), "
                        "differential evolution, or the first unless a pilot finds its "
                        "proposal fits poorly (default auto)")
    p.add_argument("--draws", type=opt.at_least(10), default=2000, metavar="N",
                   help="draws kept per beacon, at least (default 2000)")
    p.add_argument("--walkers", type=opt.at_least(12, 4096), default=None, metavar="N",
                   help="emcee walkers (default 16 with the independence proposal, "
                        "max(24, 4 x parameters) with differential evolution)")
    p.add_argument("--min-ess", type=opt.non_negative, default=1000.0, metavar="N",
                   help="run until the smallest bulk ESS reaches N and R-hat < 1.01 "
                        "(default 1000)")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (terminal) or progress lines (log file)")


#: The commands that read a pings and a beacons table, and so take the input units.
UNIT_COMMANDS = tuple(name for name, c in COMMANDS.items() if c.units)


def _add_input_units(p):
    g = p.add_argument_group("input units (bayes_mpem.io.travel_time)")
    g.add_argument("--ranges", choices=("one-way", "two-way"), default="one-way",
                   help="the range column holds one-way (default) or two-way ranges, or "
                        "travel times with --travel-time")
    g.add_argument("--travel-time", action="store_true",
                   help="the range column holds travel times (s): converted with "
                        "--sound-speed and --turnaround")
    g.add_argument("--sound-speed", type=opt.number("a sound speed in [1300, 1800] m/s",
                                                    1300.0, 1800.0),
                   default=None, metavar="C", help="--travel-time: mean sound speed, m/s")
    g.add_argument("--ssp", dest="travel_ssp", default=None, metavar="FILE",
                   help="--travel-time: a sound-speed profile (depth m, speed m/s) instead of "
                        "--sound-speed: each ping's harmonic-mean speed between the vehicle's "
                        "and the beacon's depths")
    g.add_argument("--turnaround", type=opt.turn_around, default=0.0, metavar="S",
                   help="--travel-time: the beacons' turn-around time, s (default 0)")
    g.add_argument("--origin", type=_lat_lon, default=None, metavar="LAT,LON",
                   help="tables in lat, lon: the local frame's origin (default: the "
                        "beacons' mean position)")


def _lat_lon(text: str):
    try:
        lat, lon = (float(v) for v in text.split(","))
    except ValueError:
        lat = lon = float("nan")
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise argparse.ArgumentTypeError(f"expected LAT,LON in degrees, got {text!r}")
    return lat, lon


def _units_handler(args, handler):
    """Convert travel times, two-way ranges or lat/lon first, for :data:`UNIT_COMMANDS`."""
    if not (args.travel_time or args.ranges != "one-way" or args.sound_speed is not None
            or args.travel_ssp is not None or args.turnaround or args.origin is not None
            or _has_lat_lon(args)):
        return handler

    def convert_then(a):
        from ..acoustics.profile import SoundSpeedProfile
        from ..io.travel_time import convert_survey

        ssp = None if a.travel_ssp is None else SoundSpeedProfile.from_file(a.travel_ssp)
        a.pings, a.beacons = convert_survey(
            a.pings, a.beacons, ranges=a.ranges, travel_time=a.travel_time,
            sound_speed=a.sound_speed, turnaround=a.turnaround, origin=a.origin, ssp=ssp)
        return handler(a)

    return convert_then


def _has_lat_lon(args) -> bool:
    """Whether the beacons file's header names lat and lon (and not x, y)."""
    try:
        with open(args.beacons, encoding="utf-8-sig", errors="replace") as fh:
            head = next((ln for ln in fh if ln.strip() and not ln.lstrip().startswith("#")), "")
    except OSError:
        return False
    names = {c.strip() for c in head.split(",")}
    return {"lat", "lon"} <= names and not {"x", "y"} <= names


def add_batch(sub):
    """Add ``batch``'s sub-parser."""
    p = sub.add_parser("batch", help="run a command on every survey of a manifest (Dask)")
    p.add_argument("manifest", metavar="MANIFEST",
                   help="CSV: name, pings, beacons (or name, survey, format for locate), then "
                        "option columns named as the command's options (e.g. sigma_dp)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--command", dest="batch_command", default="fit",
                   choices=[name for name, c in COMMANDS.items() if c.batch is not None],
                   help="the command run on each survey (default fit)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running Dask scheduler (default: a local cluster)")
    p.add_argument("--workers", type=opt.at_least(1, 1024), default=None, metavar="N",
                   help="workers of the local cluster (default 1)")
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")


def build_parser() -> argparse.ArgumentParser:
    """Build the parser of ``bayes-mpem``; parsed arguments carry the sub-parsers as ``subparsers``.

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
    for name, command in COMMANDS.items():
        load(command.options)(sub)
        if command.units:
            _add_input_units(sub.choices[name])
    for name in (name for name, c in COMMANDS.items() if c.palette):
        sub.choices[name].add_argument(
            "--palette", choices=PALETTES, default="okabe-ito",
            help="class colours of the figures: colour-blind safe (default) or the "
                 "paper's blue, red and green")
    for p in sub.choices.values():  # every command: options from a TOML file (_with_config)
        p.add_argument("--config", default=None, metavar="FILE.toml",
                       help="read options from this TOML file (key = the long option without "
                            "its dashes, e.g. sigma_dp = 4.0); the command line overrides it")
    parser.set_defaults(subparsers=sub.choices)
    return parser


def _output_folder(args):
    """Return the folder a command writes (checked before any work), or ``None``."""
    out = getattr(args, "out", None)
    if args.command == "stream":  # --out is where the answers go, a file or a socket
        return None
    if args.command == "plot" and out is None:
        out = args.result_dir
    if out is None:
        return None
    from ..io.results import check_output_folder  # not at import: `--help` loads no numpy

    check_output_folder(out, _out_option(args))
    return out


def _out_option(args) -> str:
    """Return the option that named the output folder (``--out`` or ``RESULT_DIR``)."""
    return "--out" if getattr(args, "out", None) is not None else "RESULT_DIR"


class _Failed(Exception):
    """A command returned a non-zero status: its files are not committed."""


#: commands whose non-zero status still leaves a result: a batch with failed surveys
#: writes them into ``failures.parquet`` beside the surveys that were done
_COMMITS_ON_FAILURE = frozenset({"batch"})


#: The run in progress, for the SIGTERM handler: ``code`` and ``out`` once its files are in
#: place (``committed``).
_DONE: dict = {}


def _on_sigterm(signum, frame):
    # not an exception: third-party code on the stack (emcee) would print it as a traceback
    from ..io.results import abort_open_runs

    if _DONE.get("committed"):  # the files are in place: they are the result
        print(f"bayes-mpem: terminated after its result was written to {_DONE.get('out')}",
              file=sys.stderr, flush=True)
        os._exit(_DONE.get("code") or 0)
    abort_open_runs()
    print("bayes-mpem: terminated; no result written", file=sys.stderr, flush=True)
    os._exit(128 + signum)


class _ReaderGone:
    """``sys.stdout`` for a run whose reader may leave (``| head``, ``| true``).

    Once a write or flush fails with :class:`BrokenPipeError` the rest of the output is
    dropped and the run goes on to write its files: before, the error ended the run after
    the work and its all-or-nothing output folder was discarded. The stream's descriptor is
    pointed at the null device so that the interpreter's last flush succeeds; ``main``
    flushes through it before putting the stream back (a pipe is block-buffered: most
    output reaches it only then). Not for ``stream``, which stops when its reader goes.
    """

    def __init__(self, stream):
        self._stream, self.gone = stream, False

    def write(self, text):
        """Write ``text``, or drop it once the reader has gone."""
        if not self.gone:
            try:
                return self._stream.write(text)
            except BrokenPipeError:
                self._lost()
        return len(text)

    def flush(self):
        """Flush, unless the reader has gone."""
        if not self.gone:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._lost()

    def _lost(self):
        self.gone = True
        with contextlib.suppress(OSError, ValueError, AttributeError):
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, self._stream.fileno())
            os.close(null)

    def __getattr__(self, name):
        return getattr(self._stream, name)


#: Options whose value is a path, by ``dest``: a relative one in a ``--config`` file is read
#: from that file's folder (docs/cli.md); the command line's stay relative to the working one.
PATH_OPTIONS = ("beacons", "travel_ssp", "ssp", "dead_reckoning", "out", "state", "replay")
#: Values of those options that are not paths: ``locate --ssp``'s keywords, ``stream``'s
#: standard input and output (``-``); ``udp://HOST:PORT`` is not one either.
NOT_PATHS = ("-", "woa09", "survey", "straight")
#: Files a command reads, checked in this order before any work: ``dest -> (option, what the
#: file is)``; a positional argument (no option) is named as its readers name it.
INPUT_FILES = {"pings": (None, "pings file"), "survey": (None, "survey file"),
               "beacons": ("--beacons", "beacons file"),
               "travel_ssp": ("--ssp", "sound-speed profile"),
               "ssp": ("--ssp", "sound-speed profile"),
               "dead_reckoning": ("--dead-reckoning", "dead-reckoning file")}


def _check_input_files(args) -> None:
    """Refuse an input file that is missing or a folder, naming the option that gave it.

    A ``--config`` file's ``ssp = "prof.txt"`` beside it said only "sound-speed profile not
    found: 'prof.txt'", after the survey was read; the message now names ``--ssp`` (and
    :func:`config_origin` the file and key it came from).
    """
    for dest, (option, what) in INPUT_FILES.items():
        path = getattr(args, dest, None)
        if not isinstance(path, str) or path in NOT_PATHS:
            continue
        lead = f"{option}: " if option else ""
        if os.path.isdir(path):
            raise InputError(f"{lead}{what} {path!r} is a folder; expected a file")
        if not os.path.exists(path):
            raise FileNotFoundError(f"{lead}{what} not found: {path!r}")



def _run(handler, args, done: dict) -> int:
    """Run ``handler`` with its files checked first and its output written all or nothing.

    ``done`` gets the handler's ``code`` and, once its files are in place, ``committed``;
    from then on a Ctrl-C is ignored (it could only report as interrupted a run whose
    result is complete: ``main`` puts the caller's handler back when it was called with
    arguments).
    """
    _check_input_files(args)
    out = _output_folder(args)
    if out is None:
        return handler(args)
    from ..io.results import writing

    done["out"] = str(out)

    def committed():
        done["committed"] = True
        with contextlib.suppress(ValueError):  # not the main thread: no handler
            signal.signal(signal.SIGINT, signal.SIG_IGN)

    try:
        with writing(out, option=_out_option(args), create=False, on_commit=committed):
            code = done["code"] = handler(args)
            if code and args.command not in _COMMITS_ON_FAILURE:
                raise _Failed(code)
    except _Failed as failed:
        return failed.args[0]
    return code


def _message(exc: BaseException) -> str:
    if isinstance(exc, OSError) and not isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: {exc.strerror or exc}"
    return str(exc)


def _config_path(argv, commands):
    """Return ``(command, --config value)`` from the raw arguments (None when absent)."""
    command = next((a for a in argv if a in commands), None)
    if command is None:
        return None, None
    rest = argv[argv.index(command) + 1:]
    for i, a in enumerate(rest):
        if a == "--config" and i + 1 < len(rest):
            return command, rest[i + 1]
        if a.startswith("--config="):
            return command, a.split("=", 1)[1]
    return command, None


def _config_tokens(sub: argparse.ArgumentParser, path: str) -> list:
    """Turn a TOML file's keys into the command-line tokens they amount to, each checked."""
    import tomllib

    def refuse(message):
        sub.error(f"--config {path}: {message}")

    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        # a byte-order mark (a file saved by Notepad or Excel) is not TOML: read past it, as
        # the CSV readers do
        doc = tomllib.loads(raw.removeprefix(b"\xef\xbb\xbf").decode("utf-8"))
    except FileNotFoundError:
        refuse("no such file")
    except IsADirectoryError:
        refuse("a folder; expected a TOML file")
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        refuse(f"not valid TOML ({exc})")
    except OSError as exc:
        refuse(f"cannot be read ({exc.strerror or exc})")
    options = {s: a for a in sub._actions for s in a.option_strings if s.startswith("--")}
    folder = os.path.dirname(path)  # a relative path in the file is read from here
    tokens, spelt = [], {}
    for key, value in doc.items():
        name = "--" + str(key).replace("_", "-")
        if name in ("--config", "--help"):
            refuse(f"key {key!r}: not an option a file can give (--{name[2:]} goes on the "
                   "command line)")
        if name in spelt:  # dr_noise and dr-noise: one option twice, one value dropped
            refuse(f"keys {spelt[name]!r} and {key!r}: one option ({name}) given twice; "
                   "give it once")
        spelt[name] = key
        action = options.get(name)
        if action is None:
            close = _closest(name, options)
            hint = f"; did you mean {close[2:].replace('-', '_')}?" if close else ""
            positional = [a.metavar or a.dest for a in sub._actions if not a.option_strings]
            refuse(f"key {key!r}: not an option of this command{hint} (positional "
                   f"arguments {', '.join(map(str, positional)) or 'none'} go on the command "
                   "line)")
        if isinstance(value, dict):
            refuse(f"key {key!r}: expected a value, got a table")
        if action.nargs == 0:  # a flag
            if not isinstance(value, bool):
                refuse(f"key {key!r}: expected true or false, got {value!r}")
            if value:
                tokens.append(name)
            continue
        items = value if isinstance(value, list) else [value]
        if isinstance(value, list) and not (isinstance(action, argparse._AppendAction)
                                            or action.nargs in ("+", "*")):
            refuse(f"key {key!r}: expected one value, got a list")
        words = []
        for v in items:
            if isinstance(v, (dict, list)) or isinstance(v, bool):
                refuse(f"key {key!r}: expected a number or text, got {v!r}")
            text = repr(v) if isinstance(v, float) else str(v)
            try:
                checked = action.type(text) if action.type else text
            except (argparse.ArgumentTypeError, ValueError, TypeError) as exc:
                refuse(f"key {key!r} ({name}): {exc}")
            if action.choices is not None and checked not in action.choices:
                refuse(f"key {key!r} ({name}): expected one of "
                       f"{', '.join(map(str, action.choices))}, got {v!r}")
            words.append(_beside(folder, text) if action.dest in PATH_OPTIONS else text)
        if isinstance(action, argparse._AppendAction):
            for w in words:
                tokens += [name, w]
        else:
            tokens += [name, *words]
    return tokens


def _beside(folder: str, text: str) -> str:
    """Return a path of a ``--config`` file as read from the file's ``folder``.

    An absolute path, a value of :data:`NOT_PATHS` and ``udp://`` stay as they are; ``~/`` is
    the home folder.
    """
    if text in NOT_PATHS or "://" in text:
        return text
    text = os.path.expanduser(text)
    return text if os.path.isabs(text) else os.path.join(folder, text)


def _closest(word: str, known):
    """Return the option of ``known`` closest to ``word``, or None."""
    import difflib

    return next(iter(difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)), None)


def _given(sub: argparse.ArgumentParser, tokens) -> list:
    """Return ``(option as typed, action, value)`` for each option of ``tokens``.

    Abbreviations are resolved as argparse resolves them (a unique prefix); a flag's value is
    the option string itself (``--gradients`` and ``--no-gradients`` differ).
    """
    longs = {s: a for a in sub._actions for s in a.option_strings if s.startswith("--")}
    out = []
    for i, word in enumerate(tokens):
        if word == "--":
            break
        if not word.startswith("--"):
            continue
        name, eq, value = word.partition("=")
        full = name if name in longs else None
        if full is None:
            hits = [s for s in longs if s.startswith(name)]
            full = hits[0] if len({longs[s] for s in hits}) == 1 else None
        if full is None:
            continue
        action = longs[full]
        if action.nargs == 0:
            out.append((name, action, full))
        elif eq:
            out.append((name, action, value))
        elif i + 1 < len(tokens):
            out.append((name, action, tokens[i + 1]))
    return out


def _check_repeated(sub: argparse.ArgumentParser, tokens) -> None:
    """Refuse an option given twice with two values on the command line (neither dropped).

    The same value twice is harmless; repeatable options (``--effect``) are not checked; a
    ``--config`` file's values are overridden by the command line's, as documented.
    """
    seen = {}
    for name, action, value in _given(sub, tokens):
        if isinstance(action, argparse._AppendAction) or action.nargs not in (None, 0):
            continue
        first = seen.setdefault(action.dest, (name, value))
        if first[1] != value:
            sub.error(f"{first[0]} {first[1]} and {name} {value}: one option given twice "
                      "with two values; give it once")


def _with_config(parser: argparse.ArgumentParser, argv) -> tuple:
    """Put a ``--config`` file's options before the command line's (which override them).

    Returns the arguments and ``{option: (file, key)}`` of the options the file set and the
    command line did not.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    commands = parser.get_default("subparsers")
    command = next((a for a in argv if a in commands), None)
    if command is not None:
        _check_repeated(commands[command], argv[argv.index(command) + 1:])
    command, path = _config_path(argv, commands)
    if path is None:
        return argv, {}
    sub = commands[command]
    at = argv.index(command) + 1
    tokens = _config_tokens(sub, path)
    typed = {a.dest for _, a, _ in _given(sub, argv[at:])}
    origin = {a.option_strings[-1 if a.nargs == 0 else 0]: (path, name[2:].replace("-", "_"))
              for name, a, _ in _given(sub, tokens) if a.dest not in typed}
    return [*argv[:at], *tokens, *argv[at:]], origin


def config_origin(message: str, origin: dict) -> str:
    """Add to ``message`` where the options it names were set, when a ``--config`` file did.

    Examples
    --------
    >>> config_origin("--seed apply with --sample only", {"--seed": ("run.toml", "seed")})
    "--seed apply with --sample only (--seed from --config run.toml, key 'seed')"
    """
    import re

    named = [o for o in origin if re.search(re.escape(o) + r"(?![\w-])", message)]
    if not named:
        return message
    return message + " (" + "; ".join(f"{o} from --config {origin[o][0]}, key {origin[o][1]!r}"
                                      for o in named) + ")"


def _parse(parser: argparse.ArgumentParser, argv):
    """Parse; an unknown option gets its sub-command's usage and the closest option's name."""
    argv, origin = _with_config(parser, argv)
    args, extra = parser.parse_known_args(argv)
    args.config_origin = origin
    if not extra:
        return args
    sub = args.subparsers.get(args.command, parser)
    known = [s for a in sub._actions for s in a.option_strings if s.startswith("--")]
    hints = []
    for word in extra:
        close = _closest(word.split("=", 1)[0], known) if word.startswith("-") else None
        if close:
            hints.append(close if len(extra) == 1 else f"{close} for {word.split('=', 1)[0]}")
    hint = f"; did you mean {', '.join(hints)}?" if hints else (
        f"; see 'bayes-mpem {args.command} --help'")
    sub.error(f"unrecognized arguments: {' '.join(extra)}{hint}")
    return args  # pragma: no cover - error() exits


def main(argv=None) -> int:
    """Entry point of ``bayes-mpem``: one ``error:`` line for invalid input (``docs/cli.md``).

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 on success, 2 on invalid input, 1 on an internal error,
        128 + signal number when terminated.

    Notes
    -----
    A Ctrl-C once the result's files are in place is ignored: the status is the command's.
    Called without ``argv`` (the program ``bayes-mpem``, whose process ends on return)
    Ctrl-C stays ignored to the end of the process (an interpreter's exit takes some
    0.5 s, and a Ctrl-C there killed it, status 130, over a complete result); called with
    ``argv``, the caller's handler is put back.
    """
    args = _parse(build_parser(), argv)  # an invalid option exits here, with status 2
    # the command line only writes files; never opens a window (matplotlib itself is
    # imported only by the commands that draw: 0.1 s); the caller's MPLBACKEND comes back
    backend = os.environ.get("MPLBACKEND")
    if "matplotlib" in sys.modules:
        sys.modules["matplotlib"].use("Agg")
    else:
        os.environ["MPLBACKEND"] = "Agg"
    try:  # the command's modules (NumPy, SciPy, pandas) load here: a second or so
        handler = load(f"{COMMANDS[args.command].module}:cmd_{args.command}")
    except KeyboardInterrupt:
        print(f"bayes-mpem {args.command}: interrupted; no result written", file=sys.stderr)
        return 130
    if args.command in UNIT_COMMANDS and not (args.command == "navigate" and args.travel_time):
        handler = _units_handler(args, handler)  # navigate traces travel times itself
    colours = contextlib.nullcontext()
    # the figures' class colours, restored on return (only when figures are drawn: the
    # plotting modules import matplotlib.pyplot)
    if getattr(args, "palette", None) and getattr(args, "figures", True):
        from ..plots.style import palette_context

        colours = palette_context(args.palette)
    previous, done = None, _DONE
    done.clear()
    interrupt = signal.getsignal(signal.SIGINT)  # ignored once the files are in place
    with contextlib.suppress(ValueError):  # not the main thread: no handler
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    with colours, warnings.catch_warnings():  # restores the caller's filters and showwarning
        warnings.simplefilter("default")
        # one line per warning, no source excerpt: messages for the user, not tracebacks
        warnings.showwarning = lambda msg, cat, *args, **kwargs: print(
            f"{cat.__name__}: {msg}", file=sys.stderr)
        stdout = sys.stdout  # stream's answers are its output: a reader gone ends it there
        if args.command != "stream":
            sys.stdout = _ReaderGone(stdout)
        try:
            return _run(handler, args, done)
        except (InputError, ValueError, OSError) as exc:
            print(f"bayes-mpem {args.command}: error: "
                  f"{config_origin(_message(exc), args.config_origin)}", file=sys.stderr)
            return 2
        except KeyboardInterrupt as exc:
            if done.get("committed"):  # after the files were put in place: they are the result
                return done["code"]
            # a batch keeps the surveys collected before Ctrl-C: its message names them
            kept = str(exc) if isinstance(exc, Interrupted) else "no result written"
            print(f"bayes-mpem {args.command}: interrupted; {kept}", file=sys.stderr)
            return 130
        except Exception as exc:
            if os.environ.get("BAYES_MPEM_TRACEBACK"):
                raise
            print(f"bayes-mpem {args.command}: internal error: {type(exc).__name__}: {exc} "
                  "(a bug: please report it with the command; BAYES_MPEM_TRACEBACK=1 shows "
                  "where)", file=sys.stderr)
            return 1
        finally:
            if isinstance(sys.stdout, _ReaderGone):
                sys.stdout.flush()  # a pipe's block buffer fails here, not at exit
            sys.stdout = stdout
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)
            if argv is not None and interrupt is not None and done.get("committed"):
                with contextlib.suppress(ValueError):
                    signal.signal(signal.SIGINT, interrupt)
            if backend is None:
                os.environ.pop("MPLBACKEND", None)
            else:
                os.environ["MPLBACKEND"] = backend


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
