"""Does ``path="auto"`` pick the right bounce geometry, and does a forced wrong one warn?

Run from the repository root::

    python benchmarks/path_choice.py             # writes its section of docs/benchmarks.md
    python benchmarks/path_choice.py --quick     # 5 seeds, prints only

For each preset (``abe58``, ``random``) and each true geometry (``triangle``,
``double``), ``--seeds`` seeded surveys (``simulate_survey(preset, rng=seed,
path=...)``) are fitted with ``fit(path="auto")`` (learned weights, as ``fit``,
``sample`` and ``compare`` choose) and with equal weights (as ``sample --priors
equal`` chooses). A survey counts as right when every beacon got its true
geometry. Then ``fit`` with the wrong geometry forced: a survey counts as warned
when every beacon drew a ``PathChoiceWarning``; and with the right one forced,
any warning is a false alarm. Acceptance: at least 19 of 20 surveys right for
each kind.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from bayes_mpem.exceptions import PathChoiceWarning
from bayes_mpem.lbl.em.path_choice import choose_path
from bayes_mpem.lbl.simulation.simulate import simulate_survey
from bayes_mpem.lbl.survey.fitting import fit

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ("abe58", "random")
KINDS = ("triangle", "double")


def _forced(sim, path):
    """Beacons that drew a PathChoiceWarning when ``path`` is forced."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = fit(sim.survey, path=path, rng=0)
    warned = {str(w.message).split(":")[0].split()[-1] for w in seen
              if issubclass(w.category, PathChoiceWarning)}
    return warned, set(res.results)


def one_survey(preset, kind, seed):
    """Measure one survey: right choices, margins, plane errors, warnings."""
    sim = simulate_survey(preset, rng=seed, path=kind)
    wrong = "double" if kind == "triangle" else "triangle"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fit(sim.survey, rng=0)
        eq_right = all(choose_path(sim.survey.for_beacon(b), weights="equal", rng=0).path == kind
                       for b in res.results)
    choices = res.path_choices
    right = all(c.path == kind for c in choices.values())
    err = [abs(r.d0 - sim.truth[b]["d0"]) for b, r in res.results.items()]
    warned, fitted = _forced(sim, wrong)
    false_alarm, _ = _forced(sim, kind)
    return {"right": right, "eq_right": eq_right, "margins": [c.margin for c in choices.values()],
            "err": err, "warned": warned == fitted, "n_warned": len(warned),
            "n_beacons": len(fitted), "false": len(false_alarm)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args(argv)
    n = 5 if args.quick else args.seeds
    lines = ["## Path choice: triangle or double bounce", "",
             f"`python benchmarks/path_choice.py` on {dt.date.today()} ({machine()}). "
             f"Per preset and true geometry, {n} seeded surveys (`simulate_survey(preset, "
             "rng=seed, path=...)`, seeds 0 to "
             f"{n - 1}, the presets' sizes). *Right*: every beacon of the survey got its true "
             "geometry from `fit(path=\"auto\")` (the choice `sample` and `compare` make too); "
             "*right, equal weights*: the same with `weights=\"equal\"` (the choice of `sample "
             "--priors equal`). *Warned*: with the wrong geometry forced, every beacon drew a "
             "`PathChoiceWarning` (beacons warned / fitted in brackets). *False alarms*: "
             "warnings with the true geometry forced. Margin: log-likelihood of the geometry "
             "chosen minus the other's, over all beacons. Plane error: |d0 - true d0| of the "
             "auto fit.", "",
             "| preset | true path | right | right, equal weights | warned (beacons) "
             "| false alarms | margin min / median (nats) | plane error median / max (m) | s |",
             "|---|---|---|---|---|---|---|---|---|"]
    worst = n
    for preset in PRESETS:
        for kind in KINDS:
            t0 = time.perf_counter()
            rows = [one_survey(preset, kind, s) for s in range(n)]
            secs = time.perf_counter() - t0
            right = sum(r["right"] for r in rows)
            worst = min(worst, right)
            margins = np.concatenate([r["margins"] for r in rows])
            err = np.concatenate([r["err"] for r in rows])
            line = (f"| {preset} | {kind} | {right}/{n} | {sum(r['eq_right'] for r in rows)}/{n} "
                    f"| {sum(r['warned'] for r in rows)}/{n} "
                    f"({sum(r['n_warned'] for r in rows)}/{sum(r['n_beacons'] for r in rows)}) "
                    f"| {sum(r['false'] for r in rows)} "
                    f"| {margins.min():.0f} / {np.median(margins):.0f} "
                    f"| {np.median(err):.2f} / {err.max():.1f} | {secs:.0f} |")
            lines.append(line)
            print(line, flush=True)
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        write_section(ROOT / "docs" / "benchmarks.md", "path_choice", text)
    return 0 if worst >= n - n // 20 else 1


if __name__ == "__main__":
    sys.exit(main())
