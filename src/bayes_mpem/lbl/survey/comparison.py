"""Equal against learned mixing priors on every beacon of a survey (``bayes-mpem compare``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import pandas as pd

from ..._rng import RNGLike, as_generator
from ...exceptions import UnusableStartError
from ...io.results import write_csv, write_json, writing
from ...io.survey import Survey
from ..bayes.loo import CLEAR, MIN_DIFF, compare_beacon
from ..bayes.posterior import check_sample_options
from ..em.path_choice import AUTO, check_path_choice, choose_path
from .model_checks import check_posterior, checks_record, warn_misfit
from .slips import load_checked
from .survey import check_min_pings, option_subset, over_beacons


@dataclass(frozen=True)
class SurveyComparison:
    """:class:`~bayes_mpem.lbl.bayes.loo.PriorComparison` of every beacon of a survey.

    Attributes
    ----------
    survey : Survey
    results : dict of str to PriorComparison
    skipped : dict of str to str
        Beacons left out, with the reason.
    path_choices : dict of str to PathChoice
        Per beacon, the multipath geometry sampled.
    checks : dict of str to list
        Per beacon, the model checks of the learned-priors posterior.
    """

    survey: Survey
    results: dict
    skipped: dict
    path_choices: dict = field(default_factory=dict)
    checks: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """Return the content of ``compare.json``.

        Returns
        -------
        dict
        """
        beacons = {b: r.to_dict() for b, r in self.results.items()}
        for b, entry in beacons.items():
            if b in self.path_choices:
                entry["path_choice"] = self.path_choices[b].to_dict()
            if b in self.checks:
                entry["model_checks"] = checks_record(self.checks[b], "posterior")
        return {"beacons": beacons,
                "skipped": dict(self.skipped),
                "rule": f"a difference is clear when |elpd_diff| > {CLEAR:g} elpd_diff_se "
                        f"and > {MIN_DIFF:g}"}

    def format_table(self) -> str:
        """Format the ELPD difference per beacon as text.

        Returns
        -------
        str
        """
        lines = [f"{'beacon':>6} {'elpd equal':>11} {'elpd learned':>12} {'diff':>8} "
                 f"{'se':>6} {'verdict':>20} {'d0 shift (m)':>12} {'changed':>7} {'path':>8}"]
        for b, r in self.results.items():
            lines.append(f"{b:>6} {r.elpd['equal'][0]:11.1f} {r.elpd['learned'][0]:12.1f} "
                         f"{r.elpd_diff:8.1f} {r.elpd_diff_se:6.1f} {r.verdict:>20} "
                         f"{r.shifts['d0']['mean_shift']:12.2f} {len(r.changed):7d} "
                         f"{r.learned.path:>8}")
        return "\n".join(lines)

    def changed(self) -> pd.DataFrame:
        """Ranges whose label changes between the two priors, every beacon in one table.

        Returns
        -------
        pandas.DataFrame
        """
        frames = [r.changed.assign(beacon=b) for b, r in self.results.items()]
        return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()

    def write(self, out_dir) -> dict:
        """Write ``compare.json`` and ``changed.csv`` to ``out_dir`` (figures: ``report.py``).

        Parameters
        ----------
        out_dir : str or pathlib.Path

        Returns
        -------
        dict
            Paths written, keyed ``compare`` and ``changed``.
        """
        with writing(out_dir) as out:
            return {"compare": write_json(out / "compare.json", self.to_dict()),
                    "changed": write_csv(out / "changed.csv", self.changed())}

    @classmethod
    def read(cls, folder) -> SurveyComparison:
        """Read a comparison back from ``compare.json``: what its figure draws.

        No survey; per beacon a namespace with ``elpd_diff``, ``elpd_diff_se``, ``shifts``
        and ``learned.em.d0`` (as :class:`~.loo.PriorComparison`): it draws, it does not write.

        Parameters
        ----------
        folder : str or pathlib.Path
            The output folder.

        Returns
        -------
        SurveyComparison
        """
        from pathlib import Path
        from types import SimpleNamespace

        from ...exceptions import InputError
        from ...io.results import read_document
        from .folder import together

        path = Path(folder) / "compare.json"
        doc = read_document(path)

        def rebuild():
            results = {}
            for b, r in doc["beacons"].items():
                if "em_d0" not in r:
                    raise InputError(f"{path}: no 'em_d0'; it was written by an older "
                                     "bayes_mpem: run 'bayes-mpem compare' again")
                results[b] = SimpleNamespace(
                    elpd_diff=r["elpd_diff"], elpd_diff_se=r["elpd_diff_se"],
                    shifts=r["shifts"], learned=SimpleNamespace(em=SimpleNamespace(d0=r["em_d0"])))
            return cls(survey=None, results=results, skipped=doc.get("skipped", {}))

        return together(folder, rebuild)


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
        Passed to :func:`~bayes_mpem.lbl.bayes.beacon_sampling.sample_beacon`; ``path`` may
        also be ``"auto"`` (the default; both priors use the geometry chosen).

    Returns
    -------
    SurveyComparison

    Raises
    ------
    ValueError
        For invalid options, before any sampling.
    SlipError
        Ranges that fit no direct path as given but do as a usual slip would (two-way
        ranges or travel times, kilometres, depths positive up: :mod:`.slips`), as
        :func:`bayes_mpem.fit`.

    Warns
    -----
    SkippedBeaconWarning, PathChoiceWarning, ModelCheckWarning
        As :func:`bayes_mpem.sample`.
    """
    path = check_path_choice(kwargs.pop("path", AUTO))
    check_sample_options(**option_subset(kwargs))
    check_min_pings(min_pings)
    survey = load_checked(pings, beacons)  # load_survey, naming the usual slips (slips.py)
    gen = as_generator(rng)
    choices = {}

    def compare_one(data):
        # stacklevel 5: choose_path, compare_one, over_beacons, compare, then its caller;
        # the chosen geometry's learned-weights fit starts the learned run (the equal
        # run fits its own, with equal weights)
        choice = choose_path(data, path, sigma_dp=kwargs.get("sigma_dp"), rng=gen,
                             fit_warnings=False, stacklevel=5)
        choices[data.beacon] = choice
        learned_init = None if "init" in kwargs else choice.fit
        return compare_beacon(data, rng=gen, path=choice.path, learned_init=learned_init,
                              **kwargs)

    results, skipped = over_beacons(survey, min_pings, compare_one,
                                    skip_on=(UnusableStartError,))
    checks = {b: check_posterior(survey.for_beacon(b), r.learned) for b, r in results.items()}
    for b, ch in checks.items():
        warn_misfit(b, ch, method="posterior", stacklevel=2)
    return SurveyComparison(survey=survey, results=results, skipped=skipped,
                            path_choices=choices, checks=checks)
