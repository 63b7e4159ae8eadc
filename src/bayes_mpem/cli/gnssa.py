"""``bayes-mpem simulate --gnssa``: write a simulated GNSS-A campaign and its truth."""

from __future__ import annotations

from .errors import OptionError

#: ``simulate`` options that only apply with ``--gnssa`` (their defaults are None).
GNSSA_ONLY = ("format", "gradients", "hours", "track")
#: the track shapes (``bayes_mpem.survey_in.gnssa_simulate.TRACKS``, without numpy)
TRACKS = ("star", "circle", "star+circle", "station")
#: ``simulate`` options of the LBL surveys, refused with ``--gnssa``: name, default (None
#: for ``--preset`` and ``--path``, whose defaults are applied later: ``--path triangle``,
#: the default given, was accepted and ignored)
LBL_ONLY = (("preset", None), ("path", None), ("n_cycles", None), ("effect", []))
#: What ``--preset`` and ``--path`` stand for when not given.
LBL_DEFAULTS = {"preset": "abe58", "path": "triangle"}


def add_simulate_gnssa(p) -> None:
    """Add the ``--gnssa`` options to the ``simulate`` sub-parser."""
    import argparse

    from . import options as opt

    g = p.add_argument_group("GNSS-A campaigns (--gnssa)")
    g.add_argument("--gnssa", action="store_true",
                   help="simulate a GNSS-A array campaign (four transponders; a sound speed "
                        "changing over hours, horizontal gradients, spurious replies, "
                        "attitude) and write it with truth.json")
    g.add_argument("--format", choices=["garpos", "gnatss"], default=None,
                   help="--gnssa: the files written (default garpos)")
    g.add_argument("--gradients", action=argparse.BooleanOptionalAction, default=None,
                   help="--gnssa: horizontal sound-speed gradients, shallow and deep "
                        "(default on)")
    g.add_argument("--hours", type=opt.number("a length in hours in (0, 48]", 0.0, 48.0,
                                                  include_low=False),
                   default=None, metavar="H", help="--gnssa: length of the campaign (default 6)")
    g.add_argument("--track", choices=TRACKS, default=None,
                   help="--gnssa: the ship's track about the array (default star+circle: "
                        "crossing lines over the array, then a circle)")


def gnssa_handler(args):
    """Return ``cmd_simulate_gnssa``, or a handler refusing options that do not go with it.

    Parameters
    ----------
    args : argparse.Namespace
        ``simulate``'s.

    Returns
    -------
    callable or None
        None when neither ``--gnssa`` nor one of its options was given.
    """
    given = [o for o in GNSSA_ONLY if getattr(args, o, None) is not None]
    if not args.gnssa and not given:
        return None
    problem = None
    if not args.gnssa:
        problem = f"{_names(given)}: only with --gnssa"
    elif args.navigation:
        problem = "--gnssa and --navigation: one kind of simulation at a time"
    else:
        from .navigate import NAVIGATION_ONLY

        lbl = [o for o, default in LBL_ONLY if getattr(args, o) != default]
        nav = [o for o in NAVIGATION_ONLY if getattr(args, o) is not None]
        if lbl or nav:
            problem = (f"{_names(lbl + nav)}: not with --gnssa (options of the LBL surveys "
                       "and dives)")
    if problem is None:
        return cmd_simulate_gnssa

    def refuse(_args):
        raise OptionError(problem)

    return refuse


def _names(options):
    return ", ".join("--" + o.replace("_", "-") for o in options)


def cmd_simulate_gnssa(args) -> int:
    """Run ``bayes-mpem simulate --gnssa``: write the campaign and ``truth.json``.

    Returns
    -------
    int
        Exit status 0.
    """
    from ..survey_in.gnssa_simulate import simulate_gnssa

    sim = simulate_gnssa(hours=6.0 if args.hours is None else args.hours, speed_model="field",
                         gradients=args.gradients is not False,
                         track=args.track or "star+circle", rng=args.seed)
    paths = sim.write(args.out, args.format or "garpos")
    t = sim.truth
    ser = t["series"]
    print(f"{len(sim.pings)} replies to {len(t['transponders'])} transponders over "
          f"{sim.settings['hours']:g} h ({int(t['spurious'].sum())} spurious); depth-averaged "
          f"sound speed {ser['dV0'].min():+.2f} to {ser['dV0'].max():+.2f} m/s about "
          f"{t['field'].v0():.2f} m/s; gradients "
          + ("off" if args.gradients is False else
             f"up to {abs(ser[['grad1_east', 'grad1_north']]).to_numpy().max():.3f} (shallow), "
             f"{abs(ser[['grad2_east', 'grad2_north']]).to_numpy().max():.3f} (deep) (m/s)/km"))
    print(f"wrote {paths['survey']}\nwrote {paths['truth']}")
    print(f"locate it with: bayes-mpem locate {paths['survey']} --out RESULT_DIR")
    return 0
