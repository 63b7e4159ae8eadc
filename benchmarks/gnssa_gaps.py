"""A campaign of two sessions a day apart: the speed spline with and without merged gaps.

Two 3-hour sessions 21 hours apart (``simulate_gnssa(hours=27, speed_model="field",
track="star+circle", gradients=True, rng=1)``, the replies of hours 3-24 removed), located
by ``locate_array_survey`` with the defaults, then with the knots kept inside the gap
(``speed_breaks`` replaced by equal intervals), twice each. Prints intervals, seconds and the
centre's error and sd (issue 26; quoted in ``docs/gnssa.md``, "Gaps in the shots")::

    OPENBLAS_NUM_THREADS=1 python benchmarks/gnssa_gaps.py
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

import bayes_mpem.survey_in.array as array_module
from bayes_mpem.survey_in.array_survey import locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa


def main() -> None:
    sim = simulate_gnssa(hours=27, speed_model="field", track="star+circle", gradients=True,
                         rng=1)
    raw = sim.raw()
    hours = raw.pings["time"].to_numpy(float) / 3600.0
    raw = dataclasses.replace(raw, pings=raw.pings[(hours < 3) | (hours > 24)]
                              .reset_index(drop=True))
    truth = sim.truth["transponders"][["east", "north", "up"]].to_numpy().mean(axis=0)
    merged = array_module.speed_breaks
    for mode in ("merged", "equal", "merged", "equal"):
        array_module.speed_breaks = merged if mode == "merged" else (
            lambda t, r, n: np.linspace(r[0], r[1], n + 1))
        t0 = time.perf_counter()
        fit = locate_array_survey(raw).fits["array"]
        m, C = fit.centre()
        print(f"{mode}: {len(raw.pings)} replies, {fit.model['speed_intervals']} intervals, "
              f"{time.perf_counter() - t0:.1f} s; centre error "
              f"{np.round(100 * (m - truth), 3)} cm, sd {np.round(100 * np.sqrt(np.diag(C)), 3)}"
              " cm", flush=True)
    array_module.speed_breaks = merged


if __name__ == "__main__":
    main()
