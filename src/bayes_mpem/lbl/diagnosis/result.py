"""What :func:`~.driver.diagnose` returns: the effects found and the fits behind them.

:class:`Effect` is one effect of the vocabulary found in the data;
:class:`Diagnosis` holds them with the baseline and final joint fits, every
extension tried and the residual checks, and writes ``diagnosis.json``. Its
figures are drawn by :func:`bayes_mpem.report.write_figures`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..._deprecated import figures_keyword
from ...io.results import output_folder, write_json
from ...io.survey import Survey
from .ecm import JointFit
from .model import Ranges

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
        One of :data:`~bayes_mpem.lbl.effects.EFFECTS`.
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
        """Return the effect as a JSON-ready dict.

        Returns
        -------
        dict
        """
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
        Effects kept, in the order they were added; empty for clean data.
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

    @property
    def unexplained(self) -> list:
        """Residual checks that fail under the final model.

        Returns
        -------
        list of dict
        """
        return [c for c in self.residual_checks if c["significant"]]

    def to_dict(self) -> dict:
        """Return the content of ``diagnosis.json``.

        Returns
        -------
        dict
        """
        d = self.data
        final = self.final.beacons(d)
        for bid, entry in final.items():
            entry["flags"] = list(self.beacon_flags.get(bid, []))
        return {
            "effects": [e.to_dict() for e in self.effects],
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
        }

    def write(self, out_dir, *, figures=None) -> dict:
        """Write ``diagnosis.json`` to ``out_dir``.

        The figures are drawn by :func:`bayes_mpem.report.write_figures`.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.
        figures : bool, optional
            Deprecated (figures are the report's job); ``True`` still draws
            them, with a DeprecationWarning.

        Returns
        -------
        dict
            Paths written, keyed ``diagnosis``.
        """
        out = output_folder(out_dir)
        paths = {"diagnosis": write_json(out / "diagnosis.json", self.to_dict(), numpy=True)}
        if figures is not None:
            paths.update(figures_keyword(self, out, figures, "Diagnosis.write(figures=...)"))
        return paths

    def summary(self) -> str:
        """Describe what was found in a few lines for a terminal.

        Returns
        -------
        str
        """
        flagged = {b: f for b, f in self.beacon_flags.items() if f}
        if not self.effects and not self.unexplained and not flagged:
            lines = ["No effect found: the paper's model explains these data "
                     f"({len(self.candidates)} extensions tried, none clearly better)."]
        elif not self.effects:
            lines = ["No effect of the vocabulary predicts these data better "
                     f"({len(self.candidates)} extensions tried), but "
                     + ("residual structure is left that the model does not explain:"
                        if self.unexplained else "some beacons' fits are not credible:")]
        else:
            lines = ["Effects found:"]
            for e in self.effects:
                lines.append(f"  {e.name}: {e.magnitude:+.4g} {e.unit}  ({e.evidence})")
        for c in self.unexplained:
            lines.append(f"  unexplained: {c['message']}")
        for bid, reasons in flagged.items():
            lines.append(f"  beacon {bid}: fit not credible: {'; '.join(reasons)}")
        return "\n".join(lines)

