"""The array posterior on the independently written generator's campaigns (issue 26).

The campaigns of ``benchmarks/gnssa_independent.py`` (scenario A: a circle, B: a staggered
star; 6 h, its defaults), each located and sampled as ``locate --sample`` does
(:func:`~bayes_mpem.survey_in.array_sampling.locate_array_survey_bayes`, seed = the
campaign's). Prints, per scenario, how often the 95 % posterior intervals of the centre and
of every coordinate hold the truth, the rms standardised error of the centre, the sampler
used, and how the shots' posterior class probabilities compare with the generator's labels::

    python benchmarks/gnssa_posterior_independent.py [N_SEEDS]

The numbers are quoted in ``docs/gnssa.md`` ("The array posterior").
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import gnssa_independent as g  # noqa: E402

from bayes_mpem.io.formats import read_survey  # noqa: E402
from bayes_mpem.survey_in.array_sampling import locate_array_survey_bayes  # noqa: E402


def scenario(scen: str, n: int) -> str:
    """Return the one-paragraph result of ``n`` campaigns of scenario ``scen``."""
    cc, tc, z, moves, p_all, t_all = [], [], [], [], [], []
    for seed in range(n):
        camp = g.campaign(seed, g.Config(scenario=scen))
        with tempfile.TemporaryDirectory() as d:
            raw = read_survey(g.write_campaign(camp, d), "garpos")
            res = locate_array_survey_bayes(raw, rng=seed, progress=False)
        r = g.compare(res.summary, camp["truth"])
        cc.append(r["centre_cov"])
        tc.append(r["tp_cov"])
        z.append(r["centre_err"] / r["centre_sd"])
        moves.append(res.summary["posterior"]["diagnostics"]["moves"].split(" (")[0])
        cls = res.classified.sort_values("line")  # the generator's shots, in file order
        p = cls["p_true"].to_numpy(float)
        p_all.append(p)
        t_all.append(np.asarray(camp["label"]) == "true")
        print(scen, seed, np.round(z[-1], 2), r["centre_cov"], moves[-1], flush=True)
    cc, tc, z = np.array(cc), np.array(tc), np.array(z)
    p, t = np.concatenate(p_all), np.concatenate(t_all)
    ok = np.isfinite(p)
    p, t = p[ok], t[ok]
    unsure = (p > 0.05) & (p < 0.95)
    return (f"{scen}: {n} campaigns; posterior centre intervals cover "
            f"{100 * cc.mean():.0f} % (east / north / up "
            + " / ".join(f"{100 * v:.0f}" for v in cc.mean(axis=0))
            + f" %), transponders' coordinates {100 * tc.mean():.0f} %; rms standardised error "
            "of the centre " + " / ".join(f"{v:.2f}" for v in np.sqrt((z ** 2).mean(axis=0)))
            + f"; sampler {', '.join(sorted(set(moves)))}; {t.size} shots, {int((~t).sum())} "
            f"outliers, {int(((p >= 0.5) != t).sum())} misclassified, {int(unsure.sum())} "
            "with p_true between 0.05 and 0.95")


def main(n: int = 10) -> None:
    for scen in ("A", "B"):
        print(scenario(scen, n), flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
