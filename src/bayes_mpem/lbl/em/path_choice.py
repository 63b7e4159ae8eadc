"""Triangle or double bounce: the multipath geometry of one beacon, chosen by likelihood."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

from ..._rng import RNGLike, as_generator
from ..._validate import check_choice
from ...exceptions import PathChoiceWarning
from ...io.survey import BeaconData
from ..model.paths import AUTO, PATH_CHOICES, PATHS
from .em_mixture import fit_mixture_em
from .em_result import EMResult

#: A forced geometry that is worse than the other by more than this many nats of
#: maximised log-likelihood draws a :class:`~bayes_mpem.exceptions.PathChoiceWarning`.
#: A likelihood ratio of e^10 (same number of parameters); ``docs/model.md``.
CLEAR_MARGIN = 10.0
RULE = "maximised mixture-EM log-likelihood"


def check_path_choice(path: str) -> str:
    """Return ``path`` if ``"auto"``, ``"triangle"`` or ``"double"``, else raise ValueError."""
    return check_choice("path", path, PATH_CHOICES)


@dataclass(frozen=True)
class PathChoice:
    """The multipath geometry of one beacon and the evidence for it.

    Attributes
    ----------
    beacon, requested, path : str
        The beacon, ``"auto"`` or the geometry forced, and the geometry used.
    loglik : dict
        Maximised mixture-EM log-likelihood of each geometry (nats).
    fits : dict
        The mixture-EM fit of each geometry.
    """

    beacon: str
    requested: str
    path: str
    loglik: dict
    fits: dict = field(repr=False, default_factory=dict)

    @property
    def fit(self) -> EMResult:
        """The mixture-EM fit of the geometry used."""
        return self.fits[self.path]

    @property
    def margin(self) -> float:
        """Log-likelihood of the geometry used minus that of the other one (nats)."""
        other = next(p for p in PATHS if p != self.path)
        return float(self.loglik[self.path] - self.loglik[other])

    def to_dict(self) -> dict:
        """JSON-ready record: ``requested``, ``path``, ``margin``, ``loglik``, ``rule``."""
        def finite(v):  # JSON has no infinity: a failed fit's -inf is written as null
            return v if math.isfinite(v) else None

        return {"requested": self.requested, "path": self.path,
                "margin": finite(self.margin),
                "loglik": {p: finite(v) for p, v in self.loglik.items()}, "rule": RULE}

    @classmethod
    def from_dict(cls, beacon: str, d: dict) -> PathChoice:
        """Rebuild a choice from its :meth:`to_dict` record (without the fits)."""
        return cls(beacon=beacon, requested=d["requested"], path=d["path"],
                   loglik={p: _score(v) for p, v in d["loglik"].items()})


def choices_from_summary(beacons: dict) -> dict:
    """Rebuild the :class:`PathChoice` of every beacon of a ``summary.json`` that records one."""
    return {b: PathChoice.from_dict(b, s["path_choice"]) for b, s in beacons.items()
            if "path_choice" in s}


def _score(ll) -> float:
    return float(ll) if ll is not None and not math.isnan(ll) else -math.inf


def _child(gen):
    """Return an independent stream from ``gen`` that leaves the draws of ``gen`` unchanged."""
    try:
        return gen.spawn(1)[0]
    except (TypeError, ValueError, AttributeError):  # a generator without a seed sequence
        return gen


def choose_path(
    data: BeaconData,
    path: str = AUTO,
    *,
    rng: RNGLike = None,
    warn_margin: float = CLEAR_MARGIN,
    fit_warnings: bool = True,
    stacklevel: int = 2,
    **kwargs,
) -> PathChoice:
    """Fit one beacon with both multipath geometries and keep the likelier (or the forced one).

    Parameters
    ----------
    path : {"auto", "triangle", "double"}
        ``"auto"`` keeps the likelier geometry; a geometry forces it (both are fitted).
    warn_margin : float, default :data:`CLEAR_MARGIN`
        Warn (PathChoiceWarning) when a forced geometry loses by more than this many nats.
    fit_warnings : bool, default True
        Issue again the warnings of the fit kept.
    **kwargs
        Passed to :func:`~bayes_mpem.lbl.em.em_mixture.fit_mixture_em` for both fits.

    Examples
    --------
    >>> from bayes_mpem.lbl.simulation.simulate import simulate_survey
    >>> sim = simulate_survey("abe58", rng=1, path="double")
    >>> choice = choose_path(sim.survey.for_beacon("4"), rng=0)
    >>> choice.path, choice.margin > 100
    ('double', True)
    """
    check_path_choice(path)
    gen = as_generator(rng)
    # the geometry asked for draws from ``gen``, the other from a child stream: the
    # caller's stream is the same whichever path is chosen
    first = PATHS[0] if path == AUTO else path
    streams = {first: gen, **{p: _child(gen) for p in PATHS if p != first}}
    fits, caught = {}, {}
    for pth in (first, *(p for p in PATHS if p != first)):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            fits[pth] = fit_mixture_em(data, path=pth, rng=streams[pth], **kwargs)
        caught[pth] = seen
    loglik = {p: _score(fits[p].loglik) for p in PATHS}
    chosen = max(PATHS, key=lambda p: loglik[p]) if path == AUTO else path
    for w in caught[chosen] if fit_warnings else ():
        warnings.warn(w.message, w.category, stacklevel=stacklevel)
    choice = PathChoice(beacon=data.beacon, requested=path, path=chosen, loglik=loglik,
                        fits=fits)
    if path != AUTO and choice.margin < -warn_margin:
        other = next(p for p in PATHS if p != path)
        warnings.warn(
            f"beacon {data.beacon} (the mixture EM's path choice): path={path!r} was forced, "
            f"but the {other} bounce is "
            f"likelier by {-choice.margin:.0f} nats (more than {warn_margin:g}); the fit "
            f"(d0={choice.fit.d0:.1f} m, sigma_MP={choice.fit.sigma_mp:.1f} m) is probably "
            f"not the reflector: use path='auto' or path={other!r}",
            PathChoiceWarning, stacklevel=stacklevel)
    return choice
