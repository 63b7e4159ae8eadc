"""What :func:`~.driver.diagnose` returns: the effects found and the fits behind them."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pandas as pd

from ...io.results import write_csv, write_json, writing
from ...io.survey import Survey
from .ecm import JointFit
from .model import Ranges, predict
from .residuals import covariates

#: The classes of a joint fit, in the columns of its ``resp``.
FIT_CLASSES = ("dp", "mp", "mp2", "ol")

_DESCRIPTION = {
    "range_bias": "every returned range is offset by a constant (e.g. a wrong turn-around time)",
    "sound_speed": "ranges are scaled by a constant factor (a wrong sound speed)",
    "plane_drift": "the reflecting plane's depth changes during the dive (tide, depth-sensor "
                   "drift)",
    "second_reflector": "a second family of multipath from another plane",
    "early_outliers": "spurious returns arrive only before the true one (first-arrival "
                      "detection)",
    "nav_drift": "the navigation drifts away from the truth over the dive",
    "beacon_bias": "one beacon's ranges are offset by a constant (its own turn-around time)",
    "beacon_position": "one beacon is not where the beacons table puts it",
}


@dataclass(frozen=True)
class Effect:
    """One effect found in the data.

    Attributes
    ----------
    name : str
        One of :data:`~bayes_mpem.lbl.simulation.effects.EFFECTS`.
    magnitude : float
        Signed size in :attr:`unit` (see :data:`UNITS`).
    unit : str
    beacons : list of str
        Beacons it acts on: all fitted beacons for a shared effect, the one
        beacon of a per-beacon effect (``beacon_bias``, ``beacon_position``).
    delta_elpd, delta_elpd_se : float
        Gain in held-out log predictive density (nats) of the final model over
        the same model without this effect (what the backward step measured;
        :mod:`~bayes_mpem.lbl.diagnosis.search`), and its standard error.
    magnitude_se : float or None
        Approximate standard error of the magnitude.
    evidence : str
        A sentence a person can read.
    detail : dict
        Extra numbers (e.g. the drift's direction).
    """

    name: str
    magnitude: float
    unit: str
    beacons: list
    delta_elpd: float
    delta_elpd_se: float
    magnitude_se: float | None
    evidence: str
    detail: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """Return the effect as a JSON-ready dict."""
        return {"name": self.name, "magnitude": self.magnitude, "unit": self.unit,
                "beacons": list(self.beacons), "delta_elpd": self.delta_elpd,
                "delta_elpd_se": self.delta_elpd_se, "magnitude_se": self.magnitude_se,
                "evidence": self.evidence, **({"detail": self.detail} if self.detail else {})}


@dataclass(frozen=True)
class Diagnosis:
    """What :func:`diagnose` found.

    Attributes
    ----------
    effects : list of Effect
        Effects found, in the order they were added; empty for clean data.
    baseline, final : JointFit
        The paper's model fitted to all beacons, and the model with the effects.
    candidates : list of dict
        Every extension tried: ``round``, ``name``, ``delta_elpd``, ``se``, ``kept``.
    residual_checks : list of dict
        Residual structure left by the final model (:func:`residual_checks`);
        ``unexplained`` lists the significant ones.
    skipped : dict
        Beacons left out, with the reason.
    survey : Survey
    data : Ranges
        The replies of every fitted beacon, as the joint fits saw them.
    settings : dict
    beacon_flags : dict
        Beacon id to the reasons its final fit is not credible
        (:func:`~bayes_mpem.lbl.diagnosis.residuals.beacon_flags`); empty lists when it is.
    withheld : list of dict
        Effects the search kept on a beacon whose final fit is not credible: not reported
        as found (:func:`~bayes_mpem.lbl.diagnosis.driver.withhold_not_credible`); each
        :meth:`Effect.to_dict` with the reason under ``withheld``.
    """

    effects: list
    baseline: JointFit
    final: JointFit
    candidates: list
    residual_checks: list
    skipped: dict
    survey: Survey = field(repr=False)
    data: Ranges = field(repr=False)
    settings: dict = field(default_factory=dict)
    beacon_flags: dict = field(default_factory=dict)
    withheld: list = field(default_factory=list)
    #: a diagnosis read back (:meth:`read`): ``diagnosis.json`` and ``replies.csv``, which
    #: :meth:`to_dict`, :meth:`replies` and :meth:`figure_info` then return
    saved: dict | None = field(default=None, repr=False)

    @property
    def unexplained(self) -> list:
        """Residual checks that fail under the final model."""
        return [c for c in self.residual_checks if c["significant"]]

    def to_dict(self) -> dict:
        """Return the content of ``diagnosis.json``."""
        if self.saved is not None:
            return self.saved["document"]
        d = self.data
        final = self.final.beacons(d)
        for bid, entry in final.items():
            entry["flags"] = list(self.beacon_flags.get(bid, []))
        return {
            "effects": [e.to_dict() for e in self.effects],
            "withheld_effects": list(self.withheld),
            "beacons": self.baseline.beacons(d),
            "final_model": {"effects": self.final.magnitudes(d),
                            "beacons": final,
                            "loglik": self.final.loglik},
            "baseline_loglik": self.baseline.loglik,
            "candidates": self.candidates,
            "unexplained": self.unexplained,
            "residual_checks": self.residual_checks,
            "skipped_beacons": self.skipped,
            "settings": self.settings,
            "figures": self.figure_info(),
        }

    def replies(self) -> pd.DataFrame:
        """Per reply, what the figures draw: covariates, residuals and classes of both fits.

        Returns
        -------
        pandas.DataFrame
            ``beacon``, ``time``, ``range``, ``elevation``, ``vehicle_depth``,
            ``bearing`` (:func:`~.residuals.covariates`), and for ``m`` in
            ``baseline``, ``final``: ``m_residual_dp``, ``m_residual_mp`` (range
            minus each class mean, m) and ``m_p_dp``, ``m_p_mp``, ``m_p_mp2``,
            ``m_p_ol``.
        """
        if self.saved is not None:
            return self.saved["replies"]
        d = self.data
        out = {"beacon": np.asarray(d.ids, dtype=object)[d.bi], **covariates(d)}
        for name, fit in (("baseline", self.baseline), ("final", self.final)):
            mu = predict(d, fit.params, fit.effects, fit.path)
            out[f"{name}_residual_dp"] = d.z - mu["dp"]
            out[f"{name}_residual_mp"] = d.z - mu["mp"]
            for c, cls in enumerate(FIT_CLASSES):
                out[f"{name}_p_{cls}"] = fit.resp[:, c]
        return pd.DataFrame(out)

    def figure_info(self) -> dict:
        """Per fit, what the figures need beside :meth:`replies`: effects, path, scatters.

        Returns
        -------
        dict
            ``{"baseline": {...}, "final": {...}}`` with ``effects``, ``path``,
            ``sigma_dp`` and ``sigma_mp`` (the median over beacons, m).
        """
        if self.saved is not None:
            return self.saved["document"]["figures"]
        return {name: {"effects": list(fit.effects), "path": fit.path,
                       "sigma_dp": float(np.median(fit.params.sigma[:, 0])),
                       "sigma_mp": float(np.median(fit.params.sigma[:, 1]))}
                for name, fit in (("baseline", self.baseline), ("final", self.final))}

    def write(self, out_dir) -> dict:
        """Write ``diagnosis.json`` and ``replies.csv`` to ``out_dir``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.

        Returns
        -------
        dict
            Paths written, keyed ``diagnosis`` and ``replies``.
        """
        with writing(out_dir) as out:
            return {"diagnosis": write_json(out / "diagnosis.json", self.to_dict(), numpy=True),
                    "replies": write_csv(out / "replies.csv", self.replies())}

    @classmethod
    def read(cls, folder) -> Diagnosis:
        """Read a diagnosis back from the folder :meth:`write` wrote: enough for its figures.

        Its fits carry ``resp``, ``effects`` and ``path`` only, its ``data`` the replies'
        ``ids``, ``bi``, ``time`` and ``nb``; no survey. A missing ``replies.csv`` is a
        ``FileNotFoundError``.

        Parameters
        ----------
        folder : str or pathlib.Path
            The output folder.

        Returns
        -------
        Diagnosis
        """
        from pathlib import Path

        from ...io.results import read_document
        from ..survey.folder import together

        d = Path(folder)
        doc = read_document(d / "diagnosis.json")
        path = d / "replies.csv"
        if not path.exists() or "figures" not in doc:
            raise FileNotFoundError(f"{path}: not found; 'bayes-mpem diagnose' writes it (a "
                                    "folder of an older bayes_mpem: run it again)")
        table = pd.read_csv(path, dtype={"beacon": str})
        beacon = table["beacon"].astype(str).to_numpy()
        ids = tuple(dict.fromkeys(beacon))
        data = SimpleNamespace(ids=ids, bi=np.array([ids.index(b) for b in beacon]),
                               time=table["time"].to_numpy(float), nb=len(ids))

        def fit(name):
            resp = np.column_stack([table[f"{name}_p_{c}"].to_numpy(float)
                                    for c in FIT_CLASSES])
            info = doc["figures"][name]
            return SimpleNamespace(resp=resp, effects=tuple(info["effects"]), path=info["path"])

        return together(d, lambda: cls(
            effects=[Effect(**e) for e in doc["effects"]], baseline=fit("baseline"),
            final=fit("final"), candidates=doc["candidates"],
            residual_checks=doc["residual_checks"], skipped=doc["skipped_beacons"],
            survey=None, data=data, settings=doc["settings"],
            beacon_flags={b: v.get("flags", []) for b, v in
                          doc["final_model"]["beacons"].items()},
            withheld=doc.get("withheld_effects", []),
            saved={"document": doc, "replies": table}))

    def summary(self) -> str:
        """Describe what was found in a few lines for a terminal."""
        flagged = {b: f for b, f in self.beacon_flags.items() if f}
        if not self.effects and not self.unexplained and not flagged:
            lines = ["No effect found: the paper's model explains these data "
                     f"({len(self.candidates)} extensions tried, none clearly better)."]
        elif self.withheld and not self.effects:
            lines = ["No effect found: what the search kept rests on fits that are not "
                     "credible:"]
        elif not self.effects:
            lines = ["No effect of the vocabulary predicts these data better "
                     f"({len(self.candidates)} extensions tried), but "
                     + ("residual structure is left that the model does not explain:"
                        if self.unexplained else "some beacons' fits are not credible:")]
        else:
            lines = ["Effects found:"]
            for e in self.effects:
                lines.append(f"  {e.name}: {e.magnitude:+.4g} {e.unit}  ({e.evidence})")
        for e in self.withheld:
            lines.append(f"  not found: {e['name']} {e['magnitude']:+.4g} {e['unit']} on beacon "
                         f"{', '.join(e['beacons'])}: the search kept it, but from a fit that "
                         "is not credible (below)")
        for c in self.unexplained:
            lines.append(f"  unexplained: {c['message']}")
        for bid, reasons in flagged.items():
            lines.append(f"  beacon {bid}: fit not credible: {'; '.join(reasons)}")
        return "\n".join(lines)
