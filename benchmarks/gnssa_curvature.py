"""The Earth's curvature in the array model, on the shipped SeaGap survey.

SeaGap's frame is along the sphere (east and north distances along it, heights above it).
Located one transponder at a time (on SeaGap's sphere, each its own speed) and as an array,
flat (the model before curvature) and on the sphere (the default), all with the survey's
profile and 5 unpenalised speed intervals, gradients off: the depth of each transponder in
the array minus its depth one at a time, and the horizontal distance between the two.

Writes the section ``gnssa-curvature`` of ``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_curvature.py
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

from bayes_mpem.io.formats import read_survey, sample_file  # noqa: E402
from bayes_mpem.survey_in.array_survey import locate_array_survey  # noqa: E402
from bayes_mpem.survey_in.survey import SEAGAP_TRANSDUCER_DEPTH, locate_survey  # noqa: E402


def main():
    """Run the comparison and write its section."""
    t0 = time.perf_counter()
    raw = read_survey(sample_file("seagap/obsdata.inp"), "seagap")
    one = locate_survey(raw, one_at_a_time=True, ssp="survey",
                        speed_intervals=5).summary["transponders"]
    up = raw.transducer_positions()
    surface = -0.5 * float(np.mean(up["tx"][2]) + np.mean(up["rx"][2])) - SEAGAP_TRANSDUCER_DEPTH
    rows = []
    for earth in ("flat", "sphere"):
        arr = locate_array_survey(raw, ssp="survey", speed_intervals=5, surface_depth=surface,
                                  earth=earth, gradients="off").summary["transponders"]
        deeper = [arr[t]["depth"]["mean"] - one[t]["depth"]["mean"] for t in sorted(one)]
        horiz = [float(np.hypot(arr[t]["east"]["mean"] - one[t]["east"]["mean"],
                                arr[t]["north"]["mean"] - one[t]["north"]["mean"]))
                 for t in sorted(one)]
        rows.append(f"| array, {earth} | " + " / ".join(f"{v:+.3f}" for v in deeper) + " | "
                    + " / ".join(f"{v:.3f}" for v in horiz) + " |")
    git = commit()
    text = "\n".join([
        f"Written by `python benchmarks/gnssa_curvature.py` ({machine()}; "
        f"{time.perf_counter() - t0:.0f} s; git {git}).",
        "",
        f"The shipped SeaGap survey ({len(raw.pings)} shots, transponders "
        f"{', '.join(sorted(one))}), its profile, 5 speed intervals, gradients off; the array "
        "against one transponder at a time (SeaGap's sphere):",
        "",
        "| model | deeper than one at a time (m), per transponder | horizontal distance (m) |",
        "|---|---|---|", *rows])
    print(text)
    write_section(ROOT / "docs" / "gnssa.md", "gnssa-curvature", text)


if __name__ == "__main__":
    main()
