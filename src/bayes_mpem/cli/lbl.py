"""The LBL sub-commands (the entries of :data:`bayes_mpem.commands.COMMANDS` naming this module)."""

from __future__ import annotations

import contextlib
import math
import sys
import warnings
from pathlib import Path

from ..io.results import write_file
from ..lbl.simulation.effects import EFFECTS
from ..lbl.simulation.simulate import simulate_survey
from ..lbl.survey.fitting import fit
from . import gnssa, navigate
from .errors import OptionError
from .output import print_written, write_result

# sample, compare, diagnose and the report (emcee, ArviZ, matplotlib) are imported by the
# commands that use them: `fit` starts without them


def fit_kwargs(args) -> dict:
    """Keyword arguments of ``fit`` from its options; ``OptionError`` for the other method's."""
    if args.method == "mixture" and (args.pol is not None or args.alpha is not None):
        raise OptionError("--pol and --alpha apply to --method paper only")
    if args.method == "paper" and args.weights is not None:
        raise OptionError("--weights applies to --method mixture only (the paper's EM has "
                          "no mixing weights)")
    return dict(method=args.method, path=args.path, sigma_dp=args.sigma_dp,
                pol=0.05 if args.pol is None else args.pol,
                alpha=0.5 if args.alpha is None else args.alpha,
                weights=args.weights or "learned", min_pings=args.min_pings, rng=args.seed)


def _sample_kwargs(args) -> dict:
    """Keyword arguments of ``sample`` and ``compare`` from their shared options."""
    if getattr(args, "priors", None) == "equal" and args.concentration is not None:
        raise OptionError("--concentration applies to --priors learned only")
    return dict(path=args.path, sigma_dp=args.sigma_dp,
                concentration=1.0 if args.concentration is None else args.concentration,
                min_pings=args.min_pings, rng=args.seed, sampler=args.sampler,
                n_draws=args.draws, n_walkers=args.walkers, min_ess=args.min_ess,
                progress=False if args.no_progress else "auto")


def sample_command_kwargs(args) -> dict:
    """Keyword arguments of :func:`~bayes_mpem.lbl.survey.sampling.sample` from ``sample``."""
    return dict(priors=args.priors, ci=args.ci, n_ensembles=args.ensembles,
                log_likelihood=args.log_likelihood, predictive=args.predictive,
                **_sample_kwargs(args))


def diagnose_kwargs(args) -> dict:
    """Keyword arguments of :func:`~bayes_mpem.lbl.diagnosis.driver.diagnose` from its options."""
    effects = EFFECTS if args.effects is None else tuple(
        e.strip() for e in args.effects.split(",") if e.strip())
    unknown = [e for e in effects if e not in EFFECTS]
    if unknown or not effects:
        raise OptionError(f"--effects: expected a comma-separated list of {', '.join(EFFECTS)}; "
                          f"got {args.effects!r}")
    return dict(effects=effects, path=args.path, n_folds=args.folds, min_gain=args.min_gain,
                min_pings=args.min_pings, rng=args.seed, progress=not args.no_progress)


def _report_fit(result, paths):
    print(result.format_table())
    for bid, res in result.results.items():
        if not res.converged:
            print(f"warning: beacon {bid} did not converge", file=sys.stderr)
    n_nr = int(result.survey.no_reply.sum())
    print(f"\n{len(result.survey)} rows, {n_nr} pings without reply (labelled no_reply)")
    if result.survey.comment_lines:
        print(f"{result.survey.comment_lines} comment line(s) (starting with #) in "
              f"{result.survey.pings_source} were not read as rows")
    print_written(paths)


def _demo_fits(sim, out, seed):
    """Fit the demo's survey with both EMs, write the fits and figures: ``(fit, paper, paths)``."""
    result = fit(sim.survey, rng=seed)
    print("Mixture EM, per beacon (cf. Table II of the paper; truth: plane at the surface,")
    print("d0 = beacon depth; sigma_MP = " + ", ".join(
        f"{b['sigma_mp']:.1f}" for b in sim.truth.values()) + " m)")
    written = write_result(result, out, truth=sim.truth)
    # the paper fixes sigma_DP; the demo fixes it at the simulation's true value
    sigma_dp = sim.truth["1"]["sigma_dp"]
    paper = fit(sim.survey, method="paper", sigma_dp=sigma_dp)
    written += write_result(paper, out / "paper", truth=sim.truth, general=False)
    print(result.format_table())
    print(f"\nThe paper's EM (Pol = 0.05, alpha = 0.5, sigma_DP fixed at the simulation's "
          f"true {sigma_dp:.2f} m):")
    print(paper.format_table())
    missed = [b for b, r in paper.results.items() if abs(r.d0 - sim.truth[b]["d0"]) > 10.0]
    if missed:
        print(f"The paper's EM missed the plane (|d0 - truth| > 10 m) on beacon(s) "
              f"{', '.join(missed)}; docs/paper-em.md explains why.")
    return result, paper, written


def _demo_bayes(sim, out, seed):
    """Sample and compare the demo's priors, write them: ``(posterior, comparison, paths)``."""
    from ..lbl.survey.comparison import compare
    from ..lbl.survey.sampling import sample

    print("\nSampling the posterior of every beacon (MCMC, learned priors)...")
    post = sample(sim.survey, rng=seed, progress="auto")
    written = write_result(post, out / "bayes", truth=sim.truth)
    print(post.format_table())
    print("\nEqual (paper) against learned mixing priors, PSIS-LOO...")
    cmp = compare(sim.survey, rng=seed, progress="auto")
    written += write_result(cmp, out / "compare")
    print(cmp.format_table())
    return post, cmp, written


@contextlib.contextmanager
def _recorded_warnings():
    """Yield a list that gets ``"Category: message"`` of every warning shown meanwhile."""
    seen, show = [], warnings.showwarning

    def record(message, category, *args, **kwargs):
        seen.append(f"{category.__name__}: {message}")
        show(message, category, *args, **kwargs)

    warnings.showwarning = record
    try:
        yield seen
    finally:
        warnings.showwarning = show


def cmd_demo(args) -> int:
    """Run ``bayes-mpem demo``: simulate, fit, sample, compare, write figures and summary.md."""
    with _recorded_warnings() as seen:
        return _demo(args, seen)


def _demo(args, seen) -> int:
    out = Path(args.out)
    sim = simulate_survey("abe58", rng=args.seed)
    written = list(sim.write(out / "survey").values())
    print(f"Simulated ABE58-like survey (seed {args.seed}): {len(sim.survey)} pings to "
          f"{len(sim.truth)} beacons\n")
    result, paper, paths = _demo_fits(sim, out, args.seed)
    written += paths
    post = cmp = None
    if not args.no_bayes:
        post, cmp, paths = _demo_bayes(sim, out, args.seed)
        written += paths
    figs = [p for p in written if str(p).endswith(".png")]
    from ..report import demo_markdown

    md = demo_markdown(sim, result, paper, out, figs, seed=args.seed, posterior=post,
                       comparison=cmp, warnings=seen)
    written.append(write_file(out / "summary.md", lambda tmp: tmp.write_text(md)))
    print(f"\nwrote {len(written)} files under {out}/ (summary.md links every figure)")
    return 0


def cmd_plot(args) -> int:
    """Run ``bayes-mpem plot``; exit status 2 when the folder holds nothing to draw."""
    from ..report import load_output, write_figures

    if _is_batch_folder(args.result_dir):
        return _plot_batch(args)
    result = load_output(args.result_dir)
    beacon = None if args.beacon is None else args.beacon.strip()  # ids are text, as in CSVs
    if beacon is not None and not hasattr(result, "results"):
        raise OptionError(f"--beacon: for folders of fitted beacons (fit, sample, compare); "
                          f"{args.result_dir} holds a {type(result).__name__} with no "
                          "per-beacon figures")
    if beacon is not None and beacon not in getattr(result, "results", {}):
        raise OptionError(f"--beacon: expected one of the fitted beacons "
                          f"{', '.join(map(repr, getattr(result, 'results', {})))}, "
                          f"got {args.beacon!r}")
    paths = write_figures(result, args.out or args.result_dir, beacon=beacon)
    if not paths:
        skipped = getattr(result, "skipped", None)
        print(f"bayes-mpem plot: {args.result_dir} holds no fitted beacon or located "
              f"transponder (skipped: {skipped or 'none'}); nothing to draw", file=sys.stderr)
        return 2
    print_written(paths)
    return 0


def _is_batch_folder(folder) -> bool:
    d = Path(folder)
    return (d / "surveys.parquet").is_file() and (d / "surveys").is_dir()


def _plot_batch(args) -> int:
    """Draw every survey of a ``bayes-mpem batch`` folder, each into ``OUT/surveys/<name>``."""
    from ..report import load_output, write_figures

    root = Path(args.result_dir)
    if args.beacon is not None:
        raise OptionError(f"--beacon: draws one survey's beacon; give that survey's folder "
                          f"({root / 'surveys' / '<name>'}), not the batch folder")
    out = Path(args.out) if args.out else root
    folders = sorted(p for p in (root / "surveys").iterdir() if (p / "summary.json").is_file())
    paths = []
    for folder in folders:
        paths += write_figures(load_output(folder), out / "surveys" / folder.name)
    if not paths:
        print(f"bayes-mpem plot: {root} is a batch folder with no complete survey to draw",
              file=sys.stderr)
        return 2
    print(f"{len(folders)} surveys of the batch drawn")
    print_written(paths)
    return 0


def cmd_simulate(args) -> int:
    """Run ``bayes-mpem simulate``: a survey, a dive (``--navigation``) or a GNSS-A campaign.

    ``OptionError`` for an ``--effect`` not ``NAME=NUMBER``, or options of another kind.
    """
    chosen = gnssa.gnssa_handler(args)  # --gnssa: a GNSS-A campaign
    if chosen is not None:
        return chosen(args)
    for name, default in gnssa.LBL_DEFAULTS.items():  # None until here: --gnssa refuses them
        if getattr(args, name) is None:
            setattr(args, name, default)
    if args.navigation:
        return navigate.cmd_simulate_navigation(args)
    given = [o for o in navigate.NAVIGATION_ONLY if getattr(args, o) is not None]
    if given:
        names = ", ".join("--" + o.replace("_", "-") for o in given)
        raise OptionError(f"{names}: only with --navigation")
    effects = {}
    for item in args.effect:
        name, sep, value = item.partition("=")
        if not sep:
            raise OptionError(f"--effect: expected NAME=NUMBER, got {item!r}")
        if name.strip() in effects:  # the first value would be dropped
            raise OptionError(f"--effect: {name.strip()} given twice ({name.strip()}="
                              f"{effects[name.strip()]!r} and {item!r}); give it once")
        if name.strip() == "beacon":  # the beacon of the per-beacon effects: an id
            effects["beacon"] = value.strip()
            continue
        try:
            effects[name.strip()] = float(value)
        except ValueError:
            raise OptionError(f"--effect: expected NAME=NUMBER, got {item!r}") from None
        if not math.isfinite(effects[name.strip()]):
            raise OptionError(f"--effect: expected NAME=NUMBER (a finite number), got {item!r}")
    sim = simulate_survey(args.preset, rng=args.seed, path=args.path, n_cycles=args.n_cycles,
                          effects=effects or None)
    paths = sim.write(args.out)
    print(f"{len(sim.survey)} pings to {len(sim.truth)} beacons")
    print_written(paths.values())
    return 0


def cmd_fit(args) -> int:
    """Run ``bayes-mpem fit``."""
    result = fit(args.pings, args.beacons, **fit_kwargs(args))
    paths = write_result(result, args.out, figures=args.figures, table_format=args.table_format)
    _report_fit(result, paths)
    return 0


def cmd_sample(args) -> int:
    """Run ``bayes-mpem sample``."""
    from ..lbl.survey.sampling import sample

    result = sample(args.pings, args.beacons, **sample_command_kwargs(args))
    paths = write_result(result, args.out, figures=args.figures, table_format=args.table_format)
    print(result.format_table())
    for bid, r in result.results.items():
        if not r.diagnostics["converged"]:
            print(f"warning: beacon {bid} (the posterior): max_steps reached before the bulk ESS "
                  f"reached {r.diagnostics['min_ess']:,.0f} and R-hat 1.01", file=sys.stderr)
    print_written(paths)
    return 0


def cmd_compare(args) -> int:
    """Run ``bayes-mpem compare``."""
    from ..lbl.survey.comparison import compare

    result = compare(args.pings, args.beacons, **_sample_kwargs(args))
    paths = write_result(result, args.out)
    print(result.format_table())
    print_written(paths)
    return 0


def cmd_diagnose(args) -> int:
    """Run ``bayes-mpem diagnose``."""
    from ..lbl.diagnosis.driver import diagnose

    result = diagnose(args.pings, args.beacons, **diagnose_kwargs(args))
    paths = write_result(result, args.out, figures=not args.no_figures)
    print(result.summary())
    print_written(paths)
    return 0
