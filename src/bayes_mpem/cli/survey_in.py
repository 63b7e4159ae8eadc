"""``bayes-mpem locate``: locate the transponders of a ranging survey file.

Parses nothing itself (:mod:`.main` does): checks that the options go
together, calls :func:`~bayes_mpem.survey_in.survey.locate_survey` (or its
posterior-sampling sibling, through :func:`bayes_mpem.batch.locate_raw`),
writes the result and prints one line per transponder.
"""

from __future__ import annotations

from pathlib import Path

from ..batch import locate_raw
from ..io.formats import read_survey
from ..survey_in.posterior import check_location_options
from .errors import OptionError


def survey_format(path, fmt: str) -> str:
    """Resolve ``--format obsrange`` to the SIO or WHOI variant of the deck-box log.

    Parameters
    ----------
    path : str or pathlib.Path
        The survey file.
    fmt : str
        The ``--format`` given.

    Returns
    -------
    str
        ``fmt``, or for ``"obsrange"`` ``"obsrange-whoi"`` when the file starts with
        a ``#`` comment header, else ``"obsrange-sio"``.
    """
    if fmt != "obsrange":
        return fmt
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        first = next((ln for ln in fh if ln.strip()), "")
    return "obsrange-whoi" if first.lstrip().startswith("#") else "obsrange-sio"


def _check_sample_options(args):
    sample_opts = (("--walkers", args.walkers), ("--min-ess", args.min_ess),
                   ("--seed", args.seed), ("--no-progress", args.no_progress or None))
    given = [name for name, v in sample_opts if v is not None]
    if given and not args.sample:
        raise OptionError(f"{', '.join(given)} apply with --sample only")
    if args.sample:
        check_location_options(n_walkers=args.walkers, ci=args.ci,
                               min_ess=1000.0 if args.min_ess is None else args.min_ess)


def locate_kwargs(args) -> dict:
    """Options of the location from ``bayes-mpem locate``'s, after checking they go together.

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    dict
        The keyword arguments of :func:`~bayes_mpem.survey_in.survey.locate_survey`,
        plus ``sample``: those of the posterior sampling
        (:func:`~bayes_mpem.survey_in.location_sampling.locate_survey_bayes`) with
        ``--sample``, else None.

    Raises
    ------
    OptionError
        For options that do not go together (e.g. ``--seed`` without ``--sample``).
    """
    _check_sample_options(args)
    model = dict(tat=args.tat, fit_tat=args.fit_tat, ci=args.ci, outliers=args.outliers,
                 ssp=args.ssp, speed_intervals=args.speed_intervals)
    if args.fit_lag:
        if args.sample:
            raise OptionError("--fit-lag with --sample is not implemented: the posterior has "
                              "no lag parameter yet")
        model["fit_lag"] = True
    model["sample"] = None if not args.sample else dict(
        n_walkers=args.walkers, min_ess=1000.0 if args.min_ess is None else args.min_ess,
        rng=0 if args.seed is None else args.seed,
        progress=False if args.no_progress else "auto")
    return model


def _print_transponder(tid, t, *, ci, sampled):
    lo, hi = t["depth"]["interval"]
    where = f"lat {t['lat']:.6f} lon {t['lon']:.6f}" if t["lat"] is not None else \
        f"east {t['east']['mean']:.2f} north {t['north']['mean']:.2f} m"
    print(f"transponder {tid}: {where}, depth {t['depth']['mean']:.2f} m "
          f"[{lo:.2f}, {hi:.2f}], sound speed {t['sound_speed']['mean']:.2f} m/s, "
          f"{t['n_spurious']} spurious of {t['n']} pings, rms {t['sigma_ms']:.2f} ms")
    if sampled:
        elo, ehi = t["em"]["depth"]["interval"]
        d = t["posterior"]["diagnostics"]
        ess = min(v for k in ("ess", "ess_bulk") for v in t["posterior"][k].values())
        print(f"  depth {100 * ci:g} % interval: posterior [{lo:.2f}, {hi:.2f}] m, "
              f"EM (Wald) [{elo:.2f}, {ehi:.2f}] m; min ESS {ess:.0f}, "
              f"{d['n_steps']} steps x {d['n_walkers']} walkers, {d['seconds']:.1f} s"
              + ("" if d["converged"] else " (NOT converged: max_steps reached)"))


def cmd_locate(args) -> int:
    """Run ``bayes-mpem locate``.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed by :func:`~bayes_mpem.cli.build_parser`.

    Returns
    -------
    int
        Exit status 0.

    Raises
    ------
    OptionError
        For options that do not go together (e.g. ``--seed`` without ``--sample``).
    """
    fmt = survey_format(args.survey, args.format)
    locate_kwargs(args)  # options checked before the file is read
    raw = read_survey(args.survey, fmt)
    result = locate_raw(raw, locate_kwargs(args))
    out = Path(args.out)
    paths = result.write(out)
    summary = result.summary
    for tid, t in summary["transponders"].items():
        _print_transponder(tid, t, ci=args.ci, sampled=args.sample)
    print(f"{summary['n_skipped_lines']} lines skipped (reasons in classified.csv)")
    print(f"wrote {paths['summary']}\nwrote {paths['classified']}")
    return 0
