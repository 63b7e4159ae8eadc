"""How long an array takes to locate, with the normal equations' arrowhead and without.

``locate_array_survey`` with its defaults (the smooth speed with knots every 5 min, gradients
``auto``, correlation ``auto``) on simulated campaigns (``star+circle``, the sound-speed field,
gradients; 4.25 h is about 3,000 replies, the issue's size) and on the shipped SeaGap survey
(3,347 replies over 14.6 h: 902 parameters with the gradients). Each is timed twice with the
arrowhead (:mod:`bayes_mpem.survey_in.arrowhead`) and twice with it switched off (the dense
factor for every evaluation, ``J'J`` dense and every weight of the intervals' grid
computed), alternating, in one run; the shorter of each pair is reported, with the largest
difference between the two paths' centres and sds.

Writes the section ``gnssa-speed`` of ``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_speed.py
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

from bayes_mpem.io.formats import read_survey, sample_file  # noqa: E402
from bayes_mpem.survey_in import array, arrowhead  # noqa: E402
from bayes_mpem.survey_in.array_survey import locate_array_survey  # noqa: E402
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

CASES = [(f"simulated {h:g} h, seed {s}", h, s) for h, s in
         ((4.25, 0), (4.25, 1), (4.25, 2), (6.0, 0), (12.0, 0), (12.0, 1))]
CASES += [("SeaGap (shipped)", None, "auto"), ("SeaGap, `--gradients off`", None, "off")]


DEFAULTS = (arrowhead.MIN_SIZE, array.GRID_SHARE)


def dense(on):
    """Switch the arrowhead off (``on=True``) or back to the package's defaults."""
    arrowhead.MIN_SIZE = 10**9 if on else DEFAULTS[0]
    array.GRID_SHARE = 0.0 if on else DEFAULTS[1]


def timed(raw, gradients):
    """Return ``(seconds, centre, sds, parameters)`` of one ``locate_array_survey``."""
    t0 = time.perf_counter()
    res = locate_array_survey(raw, gradients=gradients)
    dt = time.perf_counter() - t0
    fit = res.fits["array"]
    m, C = fit.centre()
    size = fit.enu.size + fit.speed_coef.size
    size += 0 if fit.gradient_coef is None else fit.gradient_coef.size
    return dt, m, np.sqrt(np.diag(C)), size


def main():
    """Run the cases and write the section."""
    warnings.simplefilter("ignore")
    t_all = time.perf_counter()
    rows = []
    for label, hours, arg in CASES:
        if hours is None:
            raw, gradients = read_survey(sample_file("seagap/obsdata.inp")), arg
        else:
            raw = simulate_gnssa(hours=hours, rng=arg, speed_model="field",
                                 track="star+circle", gradients=True).raw()
            gradients = "auto"
        runs = {True: [], False: []}
        for use_dense in (False, True, False, True):
            dense(use_dense)
            runs[use_dense].append(timed(raw, gradients))
        dense(False)
        fast, slow = min(runs[False]), min(runs[True])
        dm = np.abs(fast[1] - slow[1]).max()
        ds = np.abs(fast[2] / slow[2] - 1).max()
        rows.append((label, len(raw.pings), fast[3], fast[0], slow[0], dm, ds))
        print(rows[-1], flush=True)
    lines = [
        f"Written by `python benchmarks/gnssa_speed.py` ({machine()}; "
        f"{time.perf_counter() - t_all:.0f} s; git {commit()}).",
        "",
        "`locate_array_survey` with its defaults (BLAS on one thread), the shorter of two runs "
        "each way, alternating; `dense`: the arrowhead switched off in the same run (dense "
        "factors and `J'J`, every weight of the intervals' grid computed). The two paths' "
        "centres and sds compared.",
        "",
        "| campaign | replies | parameters | seconds | dense: seconds | ratio "
        "| centres differ by (m) | sds differ by (relative) |",
        "|---|---|---|---|---|---|---|---|"]
    for label, n, p, fast, slow, dm, ds in rows:
        lines.append(f"| {label} | {n} | {p} | {fast:.2f} | {slow:.2f} | {slow / fast:.1f} "
                     f"| {dm:.1e} | {ds:.1e} |")
    text = "\n".join(lines)
    print(text)
    write_section(ROOT / "docs" / "gnssa.md", "gnssa-speed", text)


if __name__ == "__main__":
    main()
