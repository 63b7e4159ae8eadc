"""Sample every beacon of a survey and write the posterior (``bayes-mpem sample``)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..._rng import RNGLike, as_generator
from ..._validate import check_choice
from ...exceptions import UnusableStartError
from ...io.results import write_file, write_json, write_table, writing
from ...io.survey import Survey
from ...io.table_files import TABLE_FORMATS
from ...mixture.densities import CLASSES
from ..bayes.beacon_sampling import PosteriorResult, sample_beacon
from ..bayes.posterior import check_sample_options
from ..em.path_choice import AUTO, check_path_choice, choose_path
from .model_checks import check_posterior, checks_record, warn_misfit
from .slips import load_checked
from .survey import (
    beacons_table,
    check_min_pings,
    classified_table,
    non_finite,
    option_subset,
    over_beacons,
)

#: The root attribute ``contents`` of each ``posterior_<id>.nc``.
CONTENTS = ("one beacon's posterior: the ArviZ groups posterior, sample_stats and "
            "observed_data (log_likelihood and posterior_predictive when asked for), the "
            "walkers as chains, each one's ensemble the chain coordinate 'ensemble'; open it "
            "with xarray.open_datatree(path), arviz_base.convert_to_datatree(path) or legacy "
            "arviz.from_netcdf(path)")


def posterior_file(bid: str) -> str:
    """Return the file name of beacon ``bid``'s posterior, ``posterior_<id>.nc`` (file-safe)."""
    return "posterior_" + re.sub(r"[^A-Za-z0-9_.-]", "_", str(bid)) + ".nc"


#: gzip with byte shuffling (netCDF4's deflate), on every variable when compressing
GZIP = {"compression": "gzip", "compression_opts": 4, "shuffle": True}


def encoding(tree, *, compress: bool = True) -> dict:
    """NetCDF encoding of every variable of ``tree``: gzip, the per-range log-likelihood float32."""
    enc = {}
    for node in tree.subtree:
        variables = {}
        for name, var in node.dataset.variables.items():
            if var.ndim == 0 or name in node.dataset.dims:
                continue
            e = dict(GZIP) if compress else {}
            if node.name == "log_likelihood" and name in node.dataset.data_vars:
                e["dtype"] = "float32"  # the values; their coordinates (ping times) stay
            if e:
                variables[name] = e
        if variables:
            enc[node.path] = variables
    return enc


@dataclass(frozen=True)
class SurveyPosterior:
    """Posteriors of every beacon of a survey.

    Attributes
    ----------
    survey : Survey
    results : dict of str to PosteriorResult
    skipped : dict of str to str
        Beacons left unfitted, with the reason.
    priors : str
    ci : float
    options : dict
    path_choices : dict of str to PathChoice
    checks : dict of str to list
        Per beacon, the model checks at the posterior means.
    """

    survey: Survey
    results: dict
    skipped: dict
    priors: str
    ci: float
    options: dict = field(default_factory=dict)
    path_choices: dict = field(default_factory=dict)
    checks: dict = field(default_factory=dict)

    def classified(self):
        """Every input row with posterior class probabilities (mean, sd), ``label``, ``reason``.

        Returns
        -------
        pandas.DataFrame
        """
        extra = {f"p_{c}_sd": {b: r.class_probs_sd[:, j] for b, r in self.results.items()}
                 for j, c in enumerate(CLASSES)}
        return classified_table(
            self.survey, {b: (r.rows, r.class_probs) for b, r in self.results.items()},
            self.skipped, extra)

    def summary(self) -> dict:
        """JSON-ready summary (see ``docs/cli.md``).

        Returns
        -------
        dict
        """
        beacons, files = {}, self.files()
        for bid, r in self.results.items():
            d = r.to_dict()
            depth = float(self.survey.beacons.loc[bid, "depth"])
            d["beacon_depth"] = depth
            lo, hi = r.summary["d0"]["interval"]
            d["plane_depth"] = {"mean": depth - r.summary["d0"]["mean"],
                                "interval": [depth - hi, depth - lo]}
            d["n"] = int(r.rows.size)
            d["file"] = files[bid]
            if bid in self.path_choices:
                d["path_choice"] = self.path_choices[bid].to_dict()
            if bid in self.checks:
                d["model_checks"] = checks_record(self.checks[bid], "posterior")
            beacons[bid] = d
        return {"priors": self.priors, "ci": self.ci, "beacons": beacons,
                "beacons_table": beacons_table(self.survey), "skipped": dict(self.skipped),
                "n_rows": len(self.survey),
                "n_no_reply": int(self.survey.no_reply.sum()),
                "pings": self.survey.pings_source, "beacons_file": self.survey.beacons_source,
                "options": {k: v for k, v in self.options.items() if k != "rng"}}

    def to_dict(self) -> dict:
        """Return the content of ``summary.json`` (the same as :meth:`summary`).

        Returns
        -------
        dict
        """
        return self.summary()

    def format_table(self) -> str:
        """Posterior means and intervals per beacon, as text.

        Returns
        -------
        str
        """
        pct = f"{100 * self.ci:g}%"
        lines = [f"{'beacon':>6} {'d0 (m)':>9} {pct + ' interval':>21} {'sigma_MP (m)':>12} "
                 f"{pct + ' interval':>15} {'depth':>7} {'w_dp':>5} {'w_mp':>5} {'w_ol':>5} "
                 f"{'min ESS':>7} {'path':>8}"]
        for bid, r in self.results.items():
            s = r.summary
            d_lo, d_hi = s["d0"]["interval"]
            m_lo, m_hi = s["sigma_mp"]["interval"]
            w = s["weights"]
            lines.append(
                f"{bid:>6} {s['d0']['mean']:9.1f} [{d_lo:8.1f}, {d_hi:8.1f}] "
                f"{s['sigma_mp']['mean']:12.2f} [{m_lo:5.2f}, {m_hi:6.2f}] "
                f"{float(self.survey.beacons.loc[bid, 'depth']):7.1f} "
                f"{w['dp']['mean']:5.3f} {w['mp']['mean']:5.3f} {w['ol']['mean']:5.3f} "
                f"{r.min_ess:7.0f} {r.path:>8}")
        for bid, why in self.skipped.items():
            lines.append(f"{bid:>6} skipped: {why}")
        return "\n".join(lines)

    def table(self) -> pd.DataFrame:
        """Per-beacon table: the columns of :meth:`SurveyFit.table`, the intervals and ``min_ess``.

        Returns
        -------
        pandas.DataFrame
        """
        rows = []
        for bid, r in self.results.items():
            depth = float(self.survey.beacons.loc[bid, "depth"])
            (d_lo, d_hi), (s_lo, s_hi) = r.summary["d0"]["interval"], r.summary["sigma_mp"][
                "interval"]
            rows.append({"beacon": bid, "d0_m": r.d0, "d0_lo_m": d_lo, "d0_hi_m": d_hi,
                         "sigma_mp_m": r.sigma_mp, "sigma_mp_lo_m": s_lo, "sigma_mp_hi_m": s_hi,
                         "beacon_depth_m": depth, "plane_depth_m": depth - r.d0,
                         "sigma_dp_m": r.sigma_dp, **r.class_fractions, "n": r.n,
                         "converged": r.converged, "path": r.path, "min_ess": r.min_ess})
        return pd.DataFrame(rows)

    def files(self) -> dict:
        """Return each beacon's posterior file name (:func:`posterior_file`, made unique).

        Returns
        -------
        dict of str to str
        """
        out, used = {}, set()
        for bid in self.results:
            name = posterior_file(bid)
            stem, k = name[:-3], 1
            while name in used:  # two ids that differ only in replaced characters
                k += 1
                name = f"{stem}-{k}.nc"
            used.add(name)
            out[bid] = name
        return out

    def write(self, out_dir, *, table_format: str = "csv", compress: bool = True) -> dict:
        """Write ``posterior_<id>.nc`` per beacon, ``classified.csv`` and, last, ``summary.json``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
        table_format : {"csv", "parquet"}, default "csv"
        compress : bool, default True

        Returns
        -------
        dict
            Paths written: ``posterior_<id>`` per beacon, ``classified``, ``summary``.
        """
        check_choice("table_format", table_format, TABLE_FORMATS)
        paths = {}
        with writing(out_dir) as out:
            for bid, name in self.files().items():
                tree = self.results[bid].idata.copy(deep=False)
                tree.attrs = {**tree.attrs, "beacon": bid, "priors": self.priors,
                              "ci": self.ci, "contents": CONTENTS}
                enc = encoding(tree, compress=compress)
                paths[name[:-3]] = write_file(out / name, lambda tmp, tree=tree, enc=enc:
                                              tree.to_netcdf(tmp, engine="h5netcdf",
                                                             encoding=enc))
            paths["classified"] = write_table(out / f"classified.{table_format}",
                                              self.classified())
            paths["summary"] = write_json(out / "summary.json", self.summary())
        return paths

    @classmethod
    def read(cls, folder) -> SurveyPosterior:
        """Read a posterior back from the folder :meth:`write` wrote, never by sampling again.

        Each beacon's ``em`` is a namespace of the EM start's parameters. A missing file is
        a ``FileNotFoundError``, files that do not fit together an ``InputError``.

        Parameters
        ----------
        folder : str or pathlib.Path
            The output folder.

        Returns
        -------
        SurveyPosterior
        """
        from pathlib import Path
        from types import SimpleNamespace

        import xarray as xr

        from ...exceptions import InputError
        from ...io.results import MARKER, read_document
        from ..em.path_choice import choices_from_summary
        from .folder import survey_and_classes, together

        d = Path(folder)
        summary = read_document(d / MARKER)
        survey, probs, num = survey_and_classes(d, summary)

        def rebuild():
            sd = np.column_stack([num["p_" + c + "_sd"] for c in CLASSES])
            results = {}
            for b, s in summary["beacons"].items():
                path = d / posterior_file(b) if "file" not in s else d / Path(s["file"]).name
                if not path.exists():
                    raise FileNotFoundError(f"{path}: not found; 'bayes-mpem sample' writes it")
                try:
                    tree = xr.open_datatree(path, engine="h5netcdf").load()
                except (OSError, ValueError) as exc:
                    raise InputError(f"{path}: not a readable NetCDF file ({exc})") from None
                rows = survey.for_beacon(b).rows
                results[b] = PosteriorResult(
                    beacon=b, priors=s["priors"], path=s["path"], idata=tree,
                    summary={k: s[k] for k in ("d0", "sigma_mp", "sigma_dp", "weights")},
                    tau=s["tau"], ess=s["ess"], ess_bulk=s.get("ess_bulk", {}),
                    rhat=s.get("rhat"), class_probs=probs[rows], class_probs_sd=sd[rows],
                    rows=rows, em=SimpleNamespace(**s.get("em", {})),
                    diagnostics=s.get("diagnostics", {}), ci=s.get("ci", summary.get("ci", 0.95)))
            return cls(survey=survey, results=results, skipped=summary.get("skipped", {}),
                       priors=summary["priors"], ci=summary.get("ci", 0.95),
                       options=summary.get("options", {}),
                       path_choices=choices_from_summary(summary["beacons"]))

        return together(d, rebuild)


def _non_finite_posterior(res) -> list:
    """Names of a posterior's summaries that are not finite (the beacon then failed)."""
    return non_finite(res.summary) + (
        [] if np.isfinite(res.class_probs).all() else ["class probabilities"])


def sample(
    pings,
    beacons=None,
    *,
    priors: str = "learned",
    ci: float = 0.95,
    min_pings: int = 30,
    rng: RNGLike = None,
    **kwargs,
) -> SurveyPosterior:
    """Sample the posterior of every beacon (each on its own, as the EM does).

    Parameters
    ----------
    pings, beacons
        As for :func:`bayes_mpem.fit`.
    priors : {"learned", "equal"}
    ci : float, default 0.95
        Probability of the reported highest-density intervals.
    min_pings : int, default 30
    rng : None, int or numpy.random.Generator
    **kwargs
        Passed to :func:`~bayes_mpem.lbl.bayes.beacon_sampling.sample_beacon`; ``path``
        may also be ``"auto"`` (the default).

    Returns
    -------
    SurveyPosterior

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
        A beacon with too few replies or an EM solution outside the prior (left unsampled);
        a forced ``path`` clearly worse than the other; ranges the model does not describe.

    Examples
    --------
    >>> import bayes_mpem
    >>> sim = bayes_mpem.simulate_survey("abe58", rng=0, n_cycles=300)
    >>> post = bayes_mpem.sample(sim.survey, rng=1, progress=False)
    >>> lo, hi = post.results["4"].summary["d0"]["interval"]
    >>> bool(lo < 2472 < hi)
    True
    """
    path = check_path_choice(kwargs.pop("path", AUTO))
    check_sample_options(priors=priors, ci=ci, **option_subset(kwargs))
    check_min_pings(min_pings)
    survey = load_checked(pings, beacons)  # load_survey, naming the usual slips (slips.py)
    gen = as_generator(rng)
    choices = {}

    def sample_one(data) -> PosteriorResult:
        # stacklevel 5: choose_path, sample_one, over_beacons, sample, then sample's caller
        choice = choose_path(data, path, sigma_dp=kwargs.get("sigma_dp"),
                             weights="learned" if priors == "learned" else "equal",
                             rng=gen, stacklevel=5)
        choices[data.beacon] = choice
        return sample_beacon(data, priors=priors, ci=ci, rng=gen, path=choice.path,
                             **{"init": choice.fit, **kwargs})

    results, skipped = over_beacons(survey, min_pings, sample_one, skip_on=(UnusableStartError,),
                                    check=_non_finite_posterior)
    checks = {bid: check_posterior(survey.for_beacon(bid), r) for bid, r in results.items()}
    for bid, ch in checks.items():
        warn_misfit(bid, ch, method="posterior", stacklevel=2)
    return SurveyPosterior(survey=survey, results=results, skipped=skipped, priors=priors,
                           ci=float(ci), options={"min_pings": min_pings, "path": path, **kwargs},
                           path_choices=choices, checks=checks)
