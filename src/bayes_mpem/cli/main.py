"""The ``bayes-mpem`` command line: thin wrappers around the library."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from .. import __version__
from ..exceptions import InputError
from ..plots.lbl import table_ii_markdown


def _add_fit_options(p):
    p.add_argument("--method", choices=["mixture", "paper"], default="mixture",
                   help="density-mixture EM (default) or the paper's EM")
    p.add_argument("--path", choices=["triangle", "double"], default="triangle",
                   help="multipath geometry: one reflected leg (default) or both")
    p.add_argument("--sigma-dp", type=float, default=None, metavar="S",
                   help="direct-path scatter in m (default: estimated from the data)")
    p.add_argument("--pol", type=float, default=None, metavar="P",
                   help="paper EM only: outlier threshold Pol (default 0.05)")
    p.add_argument("--alpha", type=float, default=None, metavar="A",
                   help="paper EM only: convergence factor alpha (default 0.5)")
    p.add_argument("--weights", choices=["learned", "equal"], default=None,
                   help="mixture EM only: learn the mixing weights (default) or fix them at 1/3")
    p.add_argument("--min-pings", type=int, default=30, metavar="N",
                   help="leave beacons with fewer replies unfitted (default 30)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``bayes-mpem`` (exposed for the docs)."""
    parser = argparse.ArgumentParser(
        prog="bayes-mpem",
        description="Classify acoustic ranges (direct path, multipath, outlier) and identify "
                    "each beacon's reflector.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("demo", help="simulate an ABE58-like survey, fit it, write figures")
    p.add_argument("--out", default="demo-output", metavar="DIR",
                   help="output folder (default: demo-output)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--no-bayes", action="store_true",
                   help="skip the Bayesian part (sampling and prior comparison, ~40 s)")

    p = sub.add_parser("plot", help="draw the figures of a fit or sample output folder")
    p.add_argument("result_dir", metavar="RESULT_DIR",
                   help="output folder of 'bayes-mpem fit' or 'bayes-mpem sample'")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="where to write (default: RESULT_DIR)")
    p.add_argument("--beacon", default=None, metavar="ID",
                   help="beacon of the single-beacon figures (default: the last one)")

    p = sub.add_parser("simulate", help="write a simulated survey (pings, beacons, truth)")
    p.add_argument("--preset", choices=["abe58", "random"], default="abe58")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--path", choices=["triangle", "double"], default="triangle")
    p.add_argument("--n-cycles", type=int, default=None, metavar="N",
                   help="number of ping cycles (default: the preset's)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help="hide an effect in the data, e.g. range_bias=5 (repeatable; names as "
                        "in 'bayes-mpem diagnose')")

    p = sub.add_parser("fit", help="fit every beacon of a survey")
    p.add_argument("pings", metavar="PINGS", help="pings CSV (time, beacon, range, x, y, depth)")
    p.add_argument("--beacons", required=True, metavar="BEACONS",
                   help="beacons CSV (beacon, x, y, depth)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--figures", action="store_true",
                   help="also write the figures (as 'bayes-mpem plot' does)")
    _add_fit_options(p)

    p = sub.add_parser("diagnose", help="find which assumption the data break (bias, sound "
                                        "speed, drifts, second reflector, early outliers)")
    p.add_argument("pings", metavar="PINGS", help="pings CSV (time, beacon, range, x, y, depth)")
    p.add_argument("--beacons", required=True, metavar="BEACONS",
                   help="beacons CSV (beacon, x, y, depth)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=int, default=0, help="random seed of the folds (default 0)")
    p.add_argument("--path", choices=["auto", "triangle", "double"], default="auto",
                   help="multipath geometry (default: the likelier of the two)")
    p.add_argument("--effects", default=None, metavar="LIST",
                   help="comma-separated candidate effects (default: all)")
    p.add_argument("--folds", type=int, default=5, metavar="K",
                   help="cross-validation folds (default 5)")
    p.add_argument("--min-gain", type=float, default=4.0, metavar="NATS",
                   help="minimum held-out gain to keep an effect (default 4)")
    p.add_argument("--min-pings", type=int, default=30, metavar="N")
    p.add_argument("--no-figures", action="store_true", help="write diagnosis.json only")
    p.add_argument("--no-progress", action="store_true", help="no progress lines on stderr")

    p = sub.add_parser("locate", help="locate a transponder from a ranging survey (EM, and "
                                      "optionally its posterior)")
    p.add_argument("survey", metavar="SURVEY", help="survey file (obsdata.inp for SeaGap)")
    p.add_argument("--format", required=True,
                   choices=["obsrange", "obsrange-sio", "obsrange-whoi", "seagap"],
                   help="'obsrange' detects the SIO or WHOI variant")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--tat", type=float, default=None, metavar="S",
                   help="turn-around time in s (default: the file's, else 0.013; SeaGap 0)")
    p.add_argument("--fit-tat", action="store_true",
                   help="fit the turn-around time too (often not identifiable)")
    p.add_argument("--ci", type=float, default=0.95, help="interval probability (default 0.95)")
    p.add_argument("--outliers", choices=["uniform", "first_arrival"], default="uniform",
                   help="spurious pings uniform over the window (default) or only before the "
                        "true arrival (a first-threshold-crossing detector)")
    p.add_argument("--ssp", default=None, metavar="FILE|woa09|survey",
                   help="refracted rays through a sound-speed profile: a two-column file "
                        "(depth m, speed m/s), 'woa09' (the atlas at the drop point) or "
                        "'survey' (the survey's own, SeaGap's ss_prof.inp); default straight rays")
    p.add_argument("--speed-intervals", type=int, default=0, metavar="N",
                   help="let the sound speed vary in time (cubic B-spline, N intervals over "
                        "the survey; default 0: one speed)")
    p.add_argument("--fit-lag", action="store_true",
                   help="fit a time lag of the acoustic position along the track (a position "
                        "fix logged at another moment, or a transducer ahead of the antenna)")
    p.add_argument("--sample", action="store_true",
                   help="after each EM fit, sample the posterior of the location and the ping "
                        "classes (emcee); intervals and classes from the posterior")
    p.add_argument("--walkers", type=int, default=None, metavar="N",
                   help="--sample: walkers (default max(32, 2 x parameters + 2))")
    p.add_argument("--min-ess", type=float, default=None, metavar="N",
                   help="--sample: run until the smallest effective sample size reaches N "
                        "(default 1000)")
    p.add_argument("--seed", type=int, default=None,
                   help="--sample: random seed (default 0); same seed, same chain")
    p.add_argument("--no-progress", action="store_true", help="--sample: hide the progress bar")

    for name, helptext in (("sample", "sample each beacon's posterior with emcee"),
                           ("compare", "compare equal (paper) and learned mixing priors by LOO")):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("pings", metavar="PINGS", help="pings CSV")
        p.add_argument("--beacons", required=True, metavar="BEACONS", help="beacons CSV")
        p.add_argument("--out", required=True, metavar="DIR")
        p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
        if name == "sample":
            p.add_argument("--priors", choices=["learned", "equal"], default="learned",
                           help="Dirichlet-learned mixing weights (default) or equal 1/3")
            p.add_argument("--ci", type=float, default=0.95,
                           help="probability of the highest-density intervals (default 0.95)")
            p.add_argument("--ensembles", type=int, default=1, metavar="K",
                           help="independent ensembles; R-hat is reported when K > 1")
            p.add_argument("--figures", action="store_true", help="also write PNG figures")
        p.add_argument("--path", choices=["triangle", "double"], default="triangle")
        p.add_argument("--sigma-dp", type=float, default=None, metavar="S",
                       help="fix sigma_DP (m) instead of sampling it")
        p.add_argument("--concentration", type=float, default=None, metavar="C",
                       help="Dirichlet concentration of the learned weights (default 1)")
        p.add_argument("--min-pings", type=int, default=30, metavar="N")
        p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


class _OptionError(ValueError):
    """An option that does not apply to the chosen method."""


def _fit_kwargs(args):
    if args.method == "mixture" and (args.pol is not None or args.alpha is not None):
        raise _OptionError("--pol and --alpha apply to --method paper only")
    if args.method == "paper" and args.weights is not None:
        raise _OptionError("--weights applies to --method mixture only (the paper's EM has "
                           "no mixing weights)")
    return dict(method=args.method, path=args.path, sigma_dp=args.sigma_dp,
                pol=0.05 if args.pol is None else args.pol,
                alpha=0.5 if args.alpha is None else args.alpha,
                weights=args.weights or "learned", min_pings=args.min_pings, rng=args.seed)


def _report(result, paths):
    print(result.format_table())
    for bid, res in result.results.items():
        if not res.converged:
            print(f"warning: beacon {bid} did not converge", file=sys.stderr)
    n_nr = int(result.survey.no_reply.sum())
    print(f"\n{len(result.survey)} rows, {n_nr} pings without reply (labelled no_reply)")
    for p in paths:
        print(f"wrote {p}")


def cmd_demo(args):
    from ..lbl.fitting import fit
    from ..lbl.simulate import simulate_survey
    from ..report import write_figures

    out = Path(args.out)
    sim = simulate_survey("abe58", rng=args.seed)
    written = list(sim.write(out / "survey").values())
    print(f"Simulated ABE58-like survey (seed {args.seed}): {len(sim.survey)} pings to "
          f"{len(sim.truth)} beacons\n")
    result = fit(sim.survey, rng=args.seed)
    print("Mixture EM, per beacon (cf. Table II of the paper; truth: plane at the surface,")
    print("HRP = beacon depth; sigma_MP = " + ", ".join(
        f"{b['sigma_mp']:.1f}" for b in sim.truth.values()) + " m)")
    written += list(result.write(out).values())
    written += write_figures(result, out, truth=sim.truth)
    paper = fit(sim.survey, method="paper", sigma_dp=sim.truth["1"]["sigma_dp"])
    written += list(paper.write(out / "paper").values())
    written += write_figures(paper, out / "paper", truth=sim.truth, general=False)
    print(result.format_table())
    print("\nThe paper's EM (Pol = 0.05, alpha = 0.5, sigma_DP = 3.97 m):")
    print(paper.format_table())
    missed = [b for b, r in paper.results.items() if abs(r.d0 - sim.truth[b]["d0"]) > 10.0]
    if missed:
        print(f"The paper's EM missed the plane (|HRP - truth| > 10 m) on beacon(s) "
              f"{', '.join(missed)}; docs/paper-em.md explains why.")
    md = ["# bayes-mpem demo", "",
          f"Simulated ABE58-like survey (seed {args.seed}): {len(sim.survey)} pings to "
          f"{len(sim.truth)} beacons. Truth: the sea surface, i.e. HRP = beacon depth.", "",
          "## Table II, mixture EM", "", table_ii_markdown(result, truth=sim.truth), "",
          "## Table II, the paper's EM (Pol = 0.05, alpha = 0.5)", "",
          table_ii_markdown(paper, truth=sim.truth), ""]
    if not args.no_bayes:
        from ..lbl.comparison import compare
        from ..lbl.sampling import sample

        print("\nSampling the posterior of every beacon (emcee, learned priors)...")
        post = sample(sim.survey, rng=args.seed, progress="auto")
        written += list(post.write(out / "bayes").values())
        written += write_figures(post, out / "bayes", truth=sim.truth)
        print(post.format_table())
        print("\nEqual (paper) against learned mixing priors, PSIS-LOO...")
        cmp = compare(sim.survey, rng=args.seed, progress="auto")
        written += list(cmp.write(out / "compare").values())
        print(cmp.format_table())
        md += ["## Posterior (learned priors)", "", "```", post.format_table(), "```", "",
               "![intervals](bayes/intervals.png)", "",
               "## Equal against learned priors", "", "```", cmp.format_table(), "```", "",
               "![compare](compare/compare.png)", ""]
    figs = [p for p in written if str(p).endswith(".png")]
    md += ["## Figures", ""] + [f"![{p.stem}]({p.relative_to(out).as_posix()})" for p in figs]
    (out / "summary.md").write_text("\n".join(md) + "\n")
    written.append(out / "summary.md")
    print(f"\nwrote {len(written)} files under {out}/ (summary.md links every figure)")
    return 0


def cmd_plot(args):
    from ..report import load_output, write_figures

    result = load_output(args.result_dir)
    if not result.results:
        print(f"bayes-mpem plot: {args.result_dir} holds no fitted beacon "
              f"(skipped: {result.skipped or 'none'}); nothing to draw", file=sys.stderr)
        return 2
    beacon = None if args.beacon is None else args.beacon.strip()  # ids are text, as in CSVs
    paths = write_figures(result, args.out or args.result_dir, beacon=beacon)
    for p in paths:
        print(f"wrote {p}")
    return 0


def cmd_simulate(args):
    from ..lbl.simulate import simulate_survey

    effects = {}
    for item in args.effect:
        name, sep, value = item.partition("=")
        try:
            effects[name.strip()] = float(value)
        except ValueError:
            raise _OptionError(f"--effect: expected NAME=NUMBER, got {item!r}") from None
        if not sep:
            raise _OptionError(f"--effect: expected NAME=NUMBER, got {item!r}")
    sim = simulate_survey(args.preset, rng=args.seed, path=args.path, n_cycles=args.n_cycles,
                          effects=effects or None)
    paths = sim.write(args.out)
    print(f"{len(sim.survey)} pings to {len(sim.truth)} beacons")
    for p in paths.values():
        print(f"wrote {p}")
    return 0


def cmd_fit(args):
    from ..lbl.fitting import fit

    result = fit(args.pings, args.beacons, **_fit_kwargs(args))
    out = Path(args.out)
    paths = list(result.write(out).values())
    if args.figures:
        from ..report import write_figures

        paths += write_figures(result, out)
    _report(result, paths)
    return 0


def _sample_kwargs(args):
    if getattr(args, "priors", None) == "equal" and args.concentration is not None:
        raise _OptionError("--concentration applies to --priors learned only")
    return dict(path=args.path, sigma_dp=args.sigma_dp,
                concentration=1.0 if args.concentration is None else args.concentration,
                min_pings=args.min_pings, rng=args.seed,
                progress=False if args.no_progress else "auto")


def cmd_sample(args):
    from ..lbl.sampling import sample

    result = sample(args.pings, args.beacons, priors=args.priors, ci=args.ci,
                    n_ensembles=args.ensembles, **_sample_kwargs(args))
    out = Path(args.out)
    paths = list(result.write(out).values())
    if args.figures:
        from ..report import write_figures

        paths += write_figures(result, out)
    print(result.format_table())
    for bid, r in result.results.items():
        if not r.diagnostics["converged"]:
            print(f"warning: beacon {bid}: chain shorter than {r.diagnostics['tau_factor']:g} "
                  "autocorrelation times", file=sys.stderr)
    for p in paths:
        print(f"wrote {p}")
    return 0


def cmd_diagnose(args):
    from ..lbl.diagnosis.driver import diagnose
    from ..lbl.diagnosis.model import EFFECTS

    effects = EFFECTS if args.effects is None else tuple(
        e.strip() for e in args.effects.split(",") if e.strip())
    result = diagnose(args.pings, args.beacons, effects=effects, path=args.path,
                      n_folds=args.folds, min_gain=args.min_gain, min_pings=args.min_pings,
                      rng=args.seed, progress=not args.no_progress)
    paths = result.write(args.out, figures=not args.no_figures)
    print(result.summary())
    for p in paths.values():
        print(f"wrote {p}")
    return 0


def cmd_locate(args):
    import json

    from ..io.formats import read_survey
    from ..survey_in.survey import locate_survey

    fmt = args.format
    if fmt == "obsrange":  # the WHOI variant starts with a '#' comment header
        with open(args.survey, encoding="utf-8-sig", errors="replace") as fh:
            first = next((ln for ln in fh if ln.strip()), "")
        fmt = "obsrange-whoi" if first.lstrip().startswith("#") else "obsrange-sio"
    sample_opts = (("--walkers", args.walkers), ("--min-ess", args.min_ess),
                   ("--seed", args.seed), ("--no-progress", args.no_progress or None))
    given = [name for name, v in sample_opts if v is not None]
    if given and not args.sample:
        raise _OptionError(f"{', '.join(given)} apply with --sample only")
    if args.sample:
        from ..survey_in.posterior import check_location_options

        check_location_options(n_walkers=args.walkers, ci=args.ci,
                               min_ess=1000.0 if args.min_ess is None else args.min_ess)
    raw = read_survey(args.survey, fmt)
    model = dict(tat=args.tat, fit_tat=args.fit_tat, ci=args.ci, outliers=args.outliers,
                 ssp=args.ssp, speed_intervals=args.speed_intervals)
    if args.fit_lag:
        if args.sample:
            raise _OptionError("--fit-lag with --sample is not implemented: the posterior has "
                               "no lag parameter yet")
        model["fit_lag"] = True
    if args.sample:
        from ..survey_in.location_sampling import locate_survey_bayes

        summary, classified, _ = locate_survey_bayes(
            raw, **model, n_walkers=args.walkers,
            min_ess=1000.0 if args.min_ess is None else args.min_ess,
            rng=0 if args.seed is None else args.seed,
            progress=False if args.no_progress else "auto")
    else:
        summary, classified = locate_survey(raw, **model)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    classified.to_csv(out / "classified.csv", index=False)
    for tid, t in summary["transponders"].items():
        lo, hi = t["depth"]["interval"]
        where = f"lat {t['lat']:.6f} lon {t['lon']:.6f}" if t["lat"] is not None else \
            f"east {t['east']['mean']:.2f} north {t['north']['mean']:.2f} m"
        print(f"transponder {tid}: {where}, depth {t['depth']['mean']:.2f} m "
              f"[{lo:.2f}, {hi:.2f}], sound speed {t['sound_speed']['mean']:.2f} m/s, "
              f"{t['n_spurious']} spurious of {t['n']} pings, rms {t['sigma_ms']:.2f} ms")
        if args.sample:
            elo, ehi = t["em"]["depth"]["interval"]
            d = t["posterior"]["diagnostics"]
            ess = min(v for k in ("ess", "ess_bulk") for v in t["posterior"][k].values())
            print(f"  depth {100 * args.ci:g} % interval: posterior [{lo:.2f}, {hi:.2f}] m, "
                  f"EM (Wald) [{elo:.2f}, {ehi:.2f}] m; min ESS {ess:.0f}, "
                  f"{d['n_steps']} steps x {d['n_walkers']} walkers, {d['seconds']:.1f} s"
                  + ("" if d["converged"] else " (NOT converged: max_steps reached)"))
    print(f"{summary['n_skipped_lines']} lines skipped (reasons in classified.csv)")
    print(f"wrote {out / 'summary.json'}\nwrote {out / 'classified.csv'}")
    return 0


def cmd_compare(args):
    from ..lbl.comparison import compare

    result = compare(args.pings, args.beacons, **_sample_kwargs(args))
    paths = result.write(args.out)
    print(result.format_table())
    for p in paths.values():
        print(f"wrote {p}")
    return 0


def main(argv=None) -> int:
    """Entry point of ``bayes-mpem``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 on success, 2 on invalid input.
    """
    args = build_parser().parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")  # the command line only writes files; never opens a window
    handler = {"demo": cmd_demo, "simulate": cmd_simulate, "fit": cmd_fit, "plot": cmd_plot,
               "sample": cmd_sample, "compare": cmd_compare, "locate": cmd_locate,
               "diagnose": cmd_diagnose}[args.command]
    with warnings.catch_warnings():  # restores the caller's filters and showwarning
        warnings.simplefilter("default")
        # one line per warning, no source excerpt: messages for the user, not tracebacks
        warnings.showwarning = lambda msg, cat, *args, **kwargs: print(
            f"{cat.__name__}: {msg}", file=sys.stderr)
        try:
            return handler(args)
        except (InputError, ValueError, FileNotFoundError) as exc:
            print(f"bayes-mpem {args.command}: error: {exc}", file=sys.stderr)
            return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
