"""The sub-commands ``navigate`` and ``simulate --navigation`` (``docs/navigate.md``)."""

from __future__ import annotations

import math

from ..lbl.model.paths import PATH_CHOICES
from ..lbl.navigate.options import MODELS, MULTIPATH
from . import options as opt
from .errors import OptionError
from .output import print_written, write_result

#: ``simulate`` options that only apply with ``--navigation``.
NAVIGATION_ONLY = ("heading_bias", "speed_scale", "dr_noise", "start_error", "shadow_range",
                   "shadow_window")


def add_navigate(sub) -> None:
    """Add ``navigate``'s sub-parser."""
    p = sub.add_parser("navigate", help="estimate the vehicle track from the ranges and a "
                                        "drifting dead reckoning, with every range's class")
    p.add_argument("pings", metavar="PINGS",
                   help="pings CSV (time, beacon, range, x, y, depth): x, y dead-reckoned, "
                        "depth the pressure depth")
    p.add_argument("--beacons", required=True, metavar="BEACONS",
                   help="beacons CSV (beacon, x, y, depth)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--dead-reckoning", default=None, metavar="FILE",
                   help="a dead-reckoning CSV at its own rate (time, x, y or time, ve, vn) "
                        "instead of the pings' x, y")
    p.add_argument("--multipath", choices=MULTIPATH, default="signal",
                   help="multipath replies carry position information (default) or are "
                        "outliers")
    p.add_argument("--model", choices=MODELS, default="mixture",
                   help="the mixture (default) or a baseline smoother")
    p.add_argument("--path", choices=PATH_CHOICES, default="auto",
                   help="multipath geometry per beacon (default auto)")
    p.add_argument("--dr-noise", type=opt.dr_noise, default=0.1, metavar="Q",
                   help="random-walk level of the dead reckoning, m/sqrt(s) (default 0.1)")
    p.add_argument("--start-sd", type=opt.start_sd, default=1000.0, metavar="M",
                   help="prior sd of the first position about the first fix, m (default 1000)")
    p.add_argument("--heading-sd", type=opt.heading_sd, default=5.0, metavar="DEG",
                   help="prior sd of the heading bias, degrees (default 5)")
    p.add_argument("--scale-sd", type=opt.scale_sd, default=0.05, metavar="S",
                   help="prior sd of the speed scale (default 0.05)")
    p.add_argument("--sigma-dp", type=opt.sigma_dp_nav, default=None, metavar="S",
                   help="fix sigma_DP, m (default: estimated)")
    p.add_argument("--range-scale", action="store_true",
                   help="also estimate a range scale (a sound-speed error), prior sd 0.01")
    p.add_argument("--transducer-offset", default=0.0, metavar="M",
                   type=opt.number("a depth offset in [-100, 100] m", -100.0, 100.0),
                   help="depth of the acoustic transducer below the pings' depth, m (default 0)")
    p.add_argument("--surface-depth", default=0.0, metavar="M",
                   type=opt.number("a depth in [-1000, 1000] m", -1000.0, 1000.0),
                   help="--travel-time --ssp: depth of the profile's sea surface in the "
                        "tables' frame, m (depths that are minus ellipsoidal heights; default 0)")
    p.add_argument("--min-pings", type=opt.at_least(1), default=30, metavar="N",
                   help="beacons with fewer replies get no multipath class (default 30)")
    p.add_argument("--max-sd", type=opt.positive, default=10.0, metavar="M",
                   help="flag epochs whose position sd stays above this, m (default 10)")
    p.add_argument("--max-iter", type=opt.at_least(1), default=300, metavar="N",
                   help="most ECM iterations (default 300)")
    p.add_argument("--tol", type=opt.positive, default=1e-3, metavar="M",
                   help="convergence: no position, plane height or scale moves more than "
                        "this in an iteration, m (default 0.001)")
    p.add_argument("--seed", type=opt.seed, default=0, help="random seed (default 0)")
    p.add_argument("--figures", action="store_true", help="also write the figures")


def add_simulate_navigation(p) -> None:
    """Add the ``--navigation`` options to the ``simulate`` sub-parser ``p``."""
    g = p.add_argument_group("dives (--navigation)")
    g.add_argument("--navigation", action="store_true",
                   help="simulate a dive: dead-reckoned pings and the true track")
    g.add_argument("--heading-bias", default=None, metavar="DEG",
                   type=opt.number("a heading bias in [-180, 180] degrees", -180.0, 180.0),
                   help="heading bias of the dead reckoning (default: drawn in [-2, 2])")
    g.add_argument("--speed-scale", type=opt.positive, default=None, metavar="S",
                   help="true over dead-reckoned speed (default: drawn in [0.98, 1.02])")
    g.add_argument("--dr-noise", type=opt.dr_noise_simulated, default=None, metavar="Q",
                   help="random walk of the dead reckoning, m/sqrt(s) (default 0.1)")
    g.add_argument("--start-error", type=opt.non_negative, default=None, metavar="M",
                   help="sd of the first fix's error, m (default 10)")
    g.add_argument("--shadow-range", type=opt.positive, default=None, metavar="M",
                   help="block the direct path beyond this horizontal range from a beacon")
    g.add_argument("--shadow-window", action="append", default=None, metavar="T0:T1",
                   help="block the direct path between these times, s (repeatable)")


def _windows(items):
    out = []
    for item in items or ():
        a, sep, b = item.partition(":")
        try:
            t0, t1 = float(a), float(b)
        except ValueError:
            t0 = t1 = float("nan")
        if not sep or not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
            raise OptionError(f"--shadow-window: expected T0:T1 (seconds, T0 < T1), got "
                              f"{item!r}")
        out.append((t0, t1))
    return out


def cmd_simulate_navigation(args) -> int:
    """Run ``bayes-mpem simulate --navigation``: write a simulated dive."""
    from ..lbl.navigate import simulate_dive

    if args.effect:
        raise OptionError("--effect does not apply with --navigation")
    kw = {k: getattr(args, k) for k in ("heading_bias", "speed_scale", "dr_noise",
                                        "start_error", "shadow_range")
          if getattr(args, k) is not None}
    sim = simulate_dive(args.preset, rng=args.seed, path=args.path, n_cycles=args.n_cycles,
                        shadow_windows=_windows(args.shadow_window), **kw)
    paths = sim.write(args.out).values()
    nav = sim.truth["navigation"]
    print(f"{len(sim.survey)} pings to {len(sim.simulation.truth)} beacons; dead reckoning: "
          f"heading bias {nav['heading_bias_deg']:.2f} deg, speed scale "
          f"{nav['speed_scale']:.4f}, random walk {nav['dr_noise']:g} m/sqrt(s); "
          f"{nav['blocked_replies']} replies with the direct path blocked")
    print_written(paths)
    return 0


def navigate_kwargs(args) -> dict:
    """Keyword arguments of :func:`~bayes_mpem.lbl.navigate.navigate` from its options."""
    travel = bool(getattr(args, "travel_time", False))
    ssp = getattr(args, "travel_ssp", None)
    if travel and ssp is not None and args.sound_speed is not None:
        raise OptionError("--travel-time: give --sound-speed or --ssp, not both")
    units = dict(travel_times=args.ranges, profile=ssp if ssp is not None else args.sound_speed,
                 turnaround=args.turnaround) if travel else {}
    return dict(dead_reckoning=args.dead_reckoning, multipath=args.multipath, model=args.model,
                path=args.path, dr_noise=args.dr_noise, start_sd=args.start_sd,
                heading_sd=args.heading_sd, scale_sd=args.scale_sd, sigma_dp=args.sigma_dp,
                range_scale=args.range_scale, **units,
                transducer_offset=getattr(args, "transducer_offset", 0.0),
                surface_depth=getattr(args, "surface_depth", 0.0),
                min_pings=args.min_pings, max_sd=args.max_sd, max_iter=args.max_iter,
                tol=args.tol, rng=args.seed)


def cmd_navigate(args) -> int:
    """Run ``bayes-mpem navigate``."""
    from ..lbl.navigate import navigate

    pings, beacons = args.pings, args.beacons
    if getattr(args, "travel_time", False):  # traced through --ssp here, not converted before
        from ..io.travel_time import convert_survey

        pings, beacons = convert_survey(pings, beacons, origin=args.origin)  # lat, lon only
    nav = navigate(pings, beacons, **navigate_kwargs(args))
    paths = write_result(nav, args.out, figures=args.figures)
    print(nav.format_table())
    print(f"\n{nav.dive.n_epochs} epochs, {nav.dive.n} replies, {len(nav.dive.survey)} rows; "
          f"{nav.n_iter} iterations, " + ("converged" if nav.converged else "NOT converged")
          + ("" if nav.corrected else "; part of the track is NOT corrected (summary.json, "
                                       "'observability')"))
    print_written(paths)
    return 0
