"""Comparison (moved from ``compare``)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from .._rng import RNGLike, as_generator
from ..exceptions import UnusableStartError
from ..io.survey import Survey, load_survey
from .loo import CLEAR, MIN_DIFF, compare_beacon
from .posterior import check_sample_options
from .survey import fittable_beacons


@dataclass(frozen=True)
class SurveyComparison:
    """:class:`PriorComparison` of every beacon of a survey."""

    survey: Survey
    results: dict
    skipped: dict

    def to_dict(self) -> dict:
        """The ``compare.json`` content."""
        return {"beacons": {b: r.to_dict() for b, r in self.results.items()},
                "skipped": dict(self.skipped),
                "rule": f"a difference is clear when |elpd_diff| > {CLEAR:g} elpd_diff_se "
                        f"and > {MIN_DIFF:g}"}

    def format_table(self) -> str:
        """ELPD difference per beacon, as text."""
        lines = [f"{'beacon':>6} {'elpd equal':>11} {'elpd learned':>12} {'diff':>8} "
                 f"{'se':>6} {'verdict':>20} {'d0 shift (m)':>12} {'changed':>7}"]
        for b, r in self.results.items():
            lines.append(f"{b:>6} {r.elpd['equal'][0]:11.1f} {r.elpd['learned'][0]:12.1f} "
                         f"{r.elpd_diff:8.1f} {r.elpd_diff_se:6.1f} {r.verdict:>20} "
                         f"{r.shifts['d0']['mean_shift']:12.2f} {len(r.changed):7d}")
        return "\n".join(lines)

    def write(self, out_dir, *, figure=True) -> dict:
        """Write ``compare.json``, ``changed.csv`` and ``compare.png`` to ``out_dir``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"compare": out / "compare.json", "changed": out / "changed.csv"}
        paths["compare"].write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        frames = [r.changed.assign(beacon=b) for b, r in self.results.items()]
        (pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()).to_csv(
            paths["changed"], index=False)
        if figure and self.results:
            import matplotlib.pyplot as plt

            from ..plots.bayes import plot_prior_comparison

            fig = plot_prior_comparison(self)
            paths["figure"] = out / "compare.png"
            fig.savefig(paths["figure"], dpi=110)
            plt.close(fig)
        return paths


def compare(pings, beacons=None, *, min_pings: int = 30, rng: RNGLike = None,
            **kwargs) -> SurveyComparison:
    """Compare equal and learned priors on every beacon of a survey.

    Parameters
    ----------
    pings, beacons
        As for :func:`bayes_mpem.fit`.
    min_pings : int, default 30
    rng : None, int or numpy.random.Generator
    **kwargs
        Passed to :func:`~bayes_mpem.bayes.sample_beacon`.

    Returns
    -------
    SurveyComparison
    """
    from .survey import option_subset, skip_beacon

    check_sample_options(**option_subset(kwargs))
    survey = load_survey(pings, beacons)
    gen = as_generator(rng)
    fittable, skipped = fittable_beacons(survey, min_pings)
    results = {}
    for d in fittable:
        try:
            results[d.beacon] = compare_beacon(d, rng=gen, **kwargs)
        except UnusableStartError as exc:
            skip_beacon(skipped, d.beacon, str(exc))
    return SurveyComparison(survey=survey, results=results, skipped=skipped)
