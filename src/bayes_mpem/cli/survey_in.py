"""``bayes-mpem locate``: locate the transponders of a ranging survey file."""

from __future__ import annotations

import inspect
from pathlib import Path

from ..batch import locate_raw
from ..exceptions import InputError
from ..io.boundary import read_text_lines
from ..io.formats import read_survey, sniff_format
from ..io.raw import ARRAY_FORMATS
from ..survey_in.posterior import check_location_options
from ..survey_in.result import (
    centre_notes,
    gradients_line,
    noise_line,
    not_fitted_note,
    positions_line,
)
from .errors import OptionError


def survey_format(path, fmt: str) -> str:
    """Resolve ``--format auto`` (sniffed) and ``obsrange`` (WHOI or SIO) to a reader's format."""
    if fmt == "auto":
        return sniff_format(path)
    if fmt != "obsrange":
        return fmt
    first = next((ln for ln in read_text_lines(path) if ln.strip()), "")
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
        # the sampler stops at max_steps (its default: locate sets no other): an effective
        # sample size above every draw it may take is never reached (1e12 ran for minutes)
        steps = inspect.signature(check_location_options).parameters["max_steps"].default
        most = (args.walkers or 32) * steps
        if args.min_ess is not None and args.min_ess > most:
            raise OptionError(f"--min-ess {args.min_ess:g}: more than the {most:,} draws the "
                              f"sampler may take ({args.walkers or 32} walkers x {steps:,} "
                              "steps); give at most that")


def _check_array_options(args, fmt):
    """Refuse array options that would change nothing: each said, none silently dropped."""
    knots, intervals = getattr(args, "knot_minutes", None), args.speed_intervals
    if knots is not None and intervals is not None:
        raise OptionError(f"--knot-minutes {knots:g} with --speed-intervals {intervals}: the knot "
                          "spacing is the smooth sound speed's (the default), which "
                          "--speed-intervals replaces; give one of the two")
    if getattr(args, "gradients", None) in ("on", "shallow") and intervals == 0:
        raise OptionError(f"--gradients {args.gradients} with --speed-intervals 0: the "
                          "gradients need a sound speed varying in time (the smooth default "
                          "or --speed-intervals N > 0)")
    if getattr(args, "flags", None) is not None and fmt != "garpos":
        raise OptionError(f"--flags: for GARPOS surveys only (a {fmt} survey has no flag "
                          "column)")
    if getattr(args, "position_prior", None) is not None and fmt != "garpos":
        raise OptionError(f"--position-prior: for GARPOS surveys only (a {fmt} survey gives "
                          "no sigmas of the prior positions)")
    if getattr(args, "no_lag_check", False):
        raise OptionError(f"--no-lag-check: for surveys located one transponder at a time (a "
                          f"{fmt} array survey has no lag check)")


def locate_kwargs(args) -> dict:
    """Options of ``locate_survey`` from ``bayes-mpem locate``'s, plus ``sample`` (or None).

    Raises ``OptionError`` for options that do not go together (``--seed`` without ``--sample``).
    """
    _check_sample_options(args)
    fmt = getattr(args, "format", None)
    one = bool(getattr(args, "one_at_a_time", False))
    if one and fmt != "seagap":
        raise OptionError(f"--one-at-a-time: for SeaGap surveys (a {fmt} survey is "
                          + ("located as an array)" if fmt in ARRAY_FORMATS else
                             "located one transponder at a time anyway)"))
    if getattr(args, "ssp", None) is not None and not args.ssp.strip():
        raise OptionError("--ssp: expected a profile file, woa09, survey or straight, got ''")
    if fmt in ARRAY_FORMATS or (fmt == "seagap" and not one):
        _check_array_options(args, fmt)
        given = [name for name, v in (("--tat", args.tat is not None),
                                      ("--fit-tat", args.fit_tat), ("--fit-lag", args.fit_lag))
                 if v]
        if given:
            also = ("; add --one-at-a-time to locate each transponder on its own"
                    if fmt == "seagap" else "")
            raise OptionError(f"{', '.join(given)}: not for a {fmt} array survey (its "
                              f"travel times are corrected for the delays){also}")
        return dict(ci=args.ci, outliers=args.outliers, ssp=args.ssp,
                    speed_intervals=args.speed_intervals, sample=_sample_options(args),
                    gradients=getattr(args, "gradients", None) or "auto",
                    knot_minutes=getattr(args, "knot_minutes", None),
                    flags=getattr(args, "flags", None) or "honour",
                    correlation=getattr(args, "correlation", None) or "auto",
                    position_prior=getattr(args, "position_prior", None) or "auto")
    if getattr(args, "position_prior", None) is not None:
        raise OptionError(f"--position-prior: for GARPOS surveys only (this {fmt} survey is "
                          "located one transponder at a time and gives no sigmas of the prior "
                          "positions)")
    array_only = [o for o in ("gradients", "knot_minutes", "flags", "correlation")
                  if getattr(args, o, None) is not None]
    if array_only:
        raise OptionError(f"{', '.join('--' + o.replace('_', '-') for o in array_only)}: for "
                          "array surveys only (GARPOS, GNATSS, SeaGap with two transponders "
                          "or more)")
    model = dict(tat=args.tat, fit_tat=args.fit_tat, ci=args.ci, outliers=args.outliers,
                 ssp=args.ssp, speed_intervals=args.speed_intervals or 0,
                 lag_check=not getattr(args, "no_lag_check", False))
    if one and not args.sample:  # the sampler locates one transponder at a time anyway
        model["one_at_a_time"] = True
    if args.fit_lag:
        if args.sample:
            raise OptionError("--fit-lag with --sample is not implemented: the posterior has "
                              "no lag parameter yet")
        model["fit_lag"] = True
    model["sample"] = _sample_options(args)
    return model


def _sample_options(args):
    """Return the sampler's options of ``locate --sample`` (None without ``--sample``)."""
    return None if not args.sample else dict(
        n_walkers=args.walkers, min_ess=1000.0 if args.min_ess is None else args.min_ess,
        rng=0 if args.seed is None else args.seed,
        progress=False if args.no_progress else "auto")


def _interval(d, fmt="{:.2f}", scale=1.0):
    lo, hi = d["interval"]
    f = fmt.format
    return f"{f(scale * d['mean'])} [{f(scale * lo)}, {f(scale * hi)}]"


def _print_transponder(tid, t, *, ci, sampled, rms=None):
    """Print one transponder's lines; ``rms``: its true replies' (an array's), else its sigma."""
    where = f"lat {t['lat']:.6f} lon {t['lon']:.6f}" if t["lat"] is not None else \
        f"east {t['east']['mean']:.2f} north {t['north']['mean']:.2f} m"
    sig = rms if rms is not None else (
        t["sigma_ms"]["mean"] if isinstance(t["sigma_ms"], dict) else t["sigma_ms"])
    print(f"transponder {tid}: {where}, depth {_interval(t['depth'])} m, "
          f"{t['n_spurious']} spurious of {t['n']} pings, rms {sig:.3g} ms")
    tat = t["tat"]
    tat_s = (_interval(tat, "{:.2f}", 1e3) if tat.get("fitted") else
             f"{1e3 * tat['mean']:.2f} (fixed)")
    print(f"  sound speed {_interval(t['sound_speed'])} m/s, TAT {tat_s} ms")
    if "enu" in t:
        print(f"  east {_interval(t['enu']['east'], '{:.3f}')}, north "
              f"{_interval(t['enu']['north'], '{:.3f}')}, up {_interval(t['enu']['up'], '{:.3f}')}"
              f" m; moved {t['moved_m']:.3f} m from its prior position")
    if "drift" in t:
        change = (f"; depth change {_interval(t['depth_change'])} m" if "depth_change" in t
                  else "")
        print(f"  drift {_interval(t['drift'])} m at azimuth {_interval(t['azimuth'], '{:.1f}')}"
              f" deg from the drop point{change}")
    lc = t.get("lag_check")
    if lc and "skipped" in lc:
        print(f"  lag check: not made, {lc['skipped']}")
    elif lc:
        verdict = ("re-run with --fit-lag" if lc["recommended"] else "no lag needed")
        print(f"  lag check: a lag of {lc['lag']:.2f} +- {lc['lag_sd']:.2f} s along the track: "
              f"held-out gain {lc['gain']:+.1f} +- {lc['gain_se']:.1f} nats, rms "
              f"{lc['rms_ms_without']:.2f} -> {lc['rms_ms_with']:.2f} ms: {verdict}")
    if "lag" in t:
        print(f"  lag {t['lag']['mean']:.2f} +- {t['lag']['sd']:.2f} s (fitted)")
    if sampled:
        lo, hi = t["depth"]["interval"]
        elo, ehi = t["em"]["depth"]["interval"]
        d = t["posterior"]["diagnostics"]
        ess = t["posterior"]["ess"]  # empty where every coordinate is held (sigma 0)
        ess = f"min ESS {min(ess.values()):.0f}" if ess else "coordinates held, not sampled"
        print(f"  depth {100 * ci:g} % interval: posterior [{lo:.2f}, {hi:.2f}] m, "
              f"EM (Wald) [{elo:.2f}, {ehi:.2f}] m; {ess}, "
              f"{d['n_steps']} steps x {d['n_walkers']} walkers, {d['seconds']:.1f} s"
              + ("" if d["converged"] else " (NOT converged: max_steps reached)"))


def _print_array_posterior(summary):
    """Print the array centre's posterior sds against the EM's, and how the chain went."""
    c = summary["array_centre"]
    sds = "/".join(f"{1e3 * c['enu'][a]['sd']:.1f}" for a in ("east", "north", "up"))
    em = "/".join(f"{1e3 * c['em']['enu'][a]['sd']:.1f}" for a in ("east", "north", "up"))
    p = summary["posterior"]
    d = p["diagnostics"]
    print(f"  centre sd east/north/up: posterior {sds} mm, EM {em} mm; min ESS "
          f"{min(p['ess'].values()):,.0f}, {d['n_steps']} steps x {d['n_walkers']} walkers, "
          f"{d['moves'].split(' (')[0]}, {d['seconds']:.1f} s"
          + ("" if d["converged"] else " (NOT converged: max_steps reached)"))


def _check_locate_output(args):
    """Refuse ``--out`` in the survey's own folder and ``--palette`` without figures."""
    here = Path(args.survey).resolve().parent
    if Path(args.out).resolve() == here:
        raise OptionError(f"--out {args.out!r}: the survey's own folder; the result's files "
                          "(summary.json, classified.csv) would mix with the campaign's: "
                          "give a folder of its own")
    if getattr(args, "palette", "okabe-ito") != "okabe-ito" and not args.figures:
        raise OptionError(f"--palette {args.palette}: colours the figures; add --figures (or "
                          "draw them later with 'bayes-mpem plot --palette')")


def _read_as(args, forced):
    """Read the survey; a file that does not read as a forced ``--format`` says so."""
    try:
        return read_survey(args.survey, args.format)
    except InputError as exc:
        if forced == "auto":
            raise
        try:
            looks = f"; the file looks like a {sniff_format(args.survey)} survey"
        except (InputError, OSError, ValueError):
            looks = ""
        raise InputError(f"{exc} (read as --format {forced}{looks})") from None


def cmd_locate(args) -> int:
    """Run ``bayes-mpem locate``."""
    forced = args.format
    _check_locate_output(args)
    args.format = survey_format(args.survey, args.format)
    options = locate_kwargs(args)  # options checked before the file is read
    raw = _read_as(args, forced)
    result = locate_raw(raw, options)
    out = Path(args.out)
    paths = result.write(out)
    summary = result.summary
    per = (summary.get("residuals") or {}).get("per_transponder", {})
    for tid, t in summary["transponders"].items():  # an array's sigma is shared: its own rms
        _print_transponder(tid, t, ci=args.ci, sampled=args.sample,
                           rms=(per.get(tid) or {}).get("rms_true"))
    if "array_centre" in summary:
        c = summary["array_centre"]["enu"]
        print(f"array centre: east {_interval(c['east'], '{:.3f}')}, north "
              f"{_interval(c['north'], '{:.3f}')}, up {_interval(c['up'], '{:.3f}')} m")
        for line in [*centre_notes(summary), positions_line(summary)]:
            if line:
                print(f"  {line}")
        print(gradients_line(summary))
        print(noise_line(summary))
        if "posterior" in summary:
            _print_array_posterior(summary)
    for tid, why in summary.get("skipped_transponders", {}).items():
        print(f"transponder {tid} not located: {why}")
    left = not_fitted_note(summary)
    if left:
        print(left)
    print(f"{summary['n_skipped_lines']} lines skipped (reasons in classified.csv)")
    written = [paths["summary"], paths["classified"]]
    written += [p for k, p in paths.items() if k.startswith("posterior_")]
    if "solution" in paths:  # an array: the plain-text solution
        written.append(paths["solution"])
    if args.figures:
        from ..report import write_figures  # matplotlib: only for figures

        written += write_figures(result, out)
    print("\n".join(f"wrote {p}" for p in written))
    return 0
