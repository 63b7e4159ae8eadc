"""The result of a one-beacon EM, its quality flags, and what both EMs share."""

from __future__ import annotations

import dataclasses
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..._validate import check_choice, check_positive, check_range
from ...exceptions import FitQualityWarning, InputError
from ...io.survey import BeaconData, check_beacon_data
from ...mixture.densities import CLASSES
from ..model import geometry
from ..model.beacon_geometry import BeaconGeometry
from ..survey.survey import MIN_PINGS

#: The mixing weights of both EMs: learned, or the paper's equal thirds.
WEIGHTS = ("learned", "equal")


def quality_flags(result, data: BeaconData, *, sigma_floor: float = 0.05) -> tuple:
    """Reasons why a fitted reflector is not credible (empty when it is).

    Parameters
    ----------
    sigma_floor : float
        The scale floor the fit used.

    Returns
    -------
    tuple of str
        Those of :func:`reflector_flags`, and more than 1 % of the ranges with no eigenray.
    """
    depth = float(data.position[2])
    flags = reflector_flags(result.resp, result.sigma_mp, depth - result.d0,
                            sigma_floor=sigma_floor,
                            plane_note=f" (d0 = {result.d0:.0f} m, beacon depth {depth:.0f} m)")
    rays = result.settings.get("refraction") if result.settings else None
    if rays and result.n and rays["no_ray"] > 0.01 * result.n:
        flags.append(f"{rays['no_ray']} of {result.n} ranges have no eigenray through the "
                     "sound-speed profile (neither direct nor multipath at the fitted plane): "
                     "they can only be outliers")
    return tuple(flags)


def reflector_flags(resp, sigma_mp, plane_depth, *, sigma_floor=0.05, plane_note=""):
    """Check a fitted reflector: the tests shared by the per-beacon EMs and the diagnosis.

    Parameters
    ----------
    resp : numpy.ndarray
        ``(n, k)`` class probabilities, direct path in column 0, multipath in 1.
    plane_depth : float
        Depth of the reflecting plane (m, positive down).
    plane_note : str, optional
        Appended to the message of a plane above the sea surface.
    """
    flags = []
    n = resp.shape[0]
    n_mp = float(resp[:, 1].sum()) if n else 0.0
    if n_mp < 10:
        flags.append(f"only {n_mp:.1f} ranges' worth of multipath: no reflector identified")
    if sigma_mp <= 1.05 * sigma_floor:
        flags.append(f"sigma_MP = {sigma_mp:.3g} m is at its floor: the multipath "
                     "component collapsed onto a few ranges")
    elif sigma_mp > 100.0:
        flags.append(f"sigma_MP = {sigma_mp:.0f} m: no coherent multipath band")
    if n and float(resp[:, 0].mean()) < 0.01:
        flags.append("almost no range matches the direct path: check the beacon position "
                     "and the navigation")
    if plane_depth < -10.0:
        flags.append(f"the plane is {-plane_depth:.0f} m above the sea surface{plane_note}")
    return flags


def with_flags(result, data, sigma_floor):
    """Copy ``result`` with its :func:`quality_flags` set (warned as FitQualityWarning)."""
    flags = quality_flags(result, data, sigma_floor=sigma_floor)
    if flags:
        fit_name = "the paper's EM" if result.method == "paper" else "the mixture EM"
        warnings.warn(f"beacon {data.beacon} ({fit_name}): " + "; ".join(flags),
                      FitQualityWarning, stacklevel=3)
    return dataclasses.replace(result, flags=flags)


@dataclass(frozen=True)
class EMResult:
    """Fit of one beacon.

    Attributes
    ----------
    beacon : str
    method : {"mixture", "paper"}
    path : {"triangle", "double"}
    d0 : float
        Height of the reflecting plane above the beacon (m).
    sigma_mp, sigma_dp : float
        Multipath and direct-path range scatter (m).
    weights : dict
        Mixing weights ``{"dp", "mp", "ol"}``; for the paper's EM (which has none) the mean
        class probabilities (the paper's Fig. 12c).
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities of every range (dp, mp, ol).
    rows : numpy.ndarray
        Positions of these ranges in the input table.
    n_iter : int
    converged : bool
    loglik : float or None
        Mixture log-likelihood (mixture EM only).
    d0_se : float or None
        Approximate standard error of ``d0`` (m, mixture EM only; ``docs/recovery.md``).
    flags : tuple of str
        Why the result is not a credible reflector (:func:`quality_flags`).
    history : dict of numpy.ndarray
        Per-iteration values, index 0 the start.
    first_resp : numpy.ndarray
        Class probabilities after the first E-step (the paper's Fig. 7).
    settings : dict
        The options the fit ran with.
    """

    beacon: str
    method: str
    path: str
    d0: float
    sigma_mp: float
    sigma_dp: float
    weights: dict
    resp: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    n_iter: int
    converged: bool
    loglik: float | None
    history: dict = field(repr=False)
    first_resp: np.ndarray = field(repr=False)
    settings: dict = field(default_factory=dict)
    d0_se: float | None = None
    flags: tuple = ()

    @property
    def n(self) -> int:
        """Number of ranges used."""
        return int(self.resp.shape[0])

    @property
    def labels(self) -> np.ndarray:
        """Most probable class of every range (``"dp"``, ``"mp"`` or ``"ol"``)."""
        return np.asarray(CLASSES)[np.argmax(self.resp, axis=1)]

    @property
    def class_probs(self) -> np.ndarray:
        """``(n, 3)`` class probabilities (dp, mp, ol): ``resp``, by PosteriorResult's name."""
        return self.resp

    @property
    def class_fractions(self) -> dict:
        """Fraction of ranges labelled dp, mp and ol."""
        lab = np.argmax(self.resp, axis=1)
        return {c: float(np.mean(lab == j)) if self.n else float("nan")
                for j, c in enumerate(CLASSES)}

    def to_dict(self) -> dict:
        """JSON-ready summary (no per-range arrays)."""
        return {
            "d0": self.d0,
            "sigma_mp": self.sigma_mp,
            "sigma_dp": self.sigma_dp,
            "weights": dict(self.weights),
            "class_fractions": self.class_fractions,
            "n": self.n,
            "iterations": self.n_iter,
            "converged": self.converged,
            "loglik": self.loglik,
            "d0_se": self.d0_se,
            "flags": list(self.flags),
            "method": self.method,
            "path": self.path,
            "settings": dict(self.settings),
        }


# --------------------------------------------------------------------------
# shared helpers


def estimate_sigma_dp(geom: BeaconGeometry, *, window: float = 50.0) -> float:
    """Robust direct-path scatter (m): residuals within ``window`` m trimmed at 3 sigma.

    Parameters
    ----------
    window : float
        Half-width (m) of the residuals ``z - L_direct`` considered.

    Returns
    -------
    float
        1.0 if fewer than 5 ranges fall in the window.
    """
    r = geom.z - geom.direct
    r = r[np.abs(r) < window]
    if r.size < 5:
        return 1.0
    s = 1.4826 * np.median(np.abs(r - np.median(r)))
    for _ in range(20):
        keep = r[np.abs(r - r.mean()) < 3.0 * max(s, 1e-3)]
        s_new = float(keep.std()) if keep.size >= 5 else s
        if abs(s_new - s) < 1e-6:
            break
        s = s_new
    return max(float(s), 1e-3)


def wdot(w, x):
    """Return ``sum(w * x)`` by a NumPy reduction (a BLAS ``ddot`` spin-waits on busy cores)."""
    return float(np.add.reduce(w * x))


def check_options(*, path="triangle", weights="learned", pol=0.05, alpha=0.5, sigma_dp=None):
    """Validate the options of both EMs; return ``sigma_dp`` as a float or None.

    Raises
    ------
    ValueError
        Naming the first bad option.
    """
    geometry.check_path(path)
    check_choice("weights", weights, WEIGHTS, words=True)
    check_range("pol", pol, low=0, high=1)
    check_range("alpha", alpha, low=0, high=1, include_high=True)
    return check_positive("sigma_dp", sigma_dp, allow_none=True, what="a positive number")


def check_fit_data(data) -> BeaconData:
    """Return ``data`` if either EM can fit it: one beacon's replies, at least 3 ranges.

    The paper's EM ran on 0 ranges (its start value back, with NaN weights) and called a fit
    of 1 range converged, where the mixture EM refused fewer than 3.

    Parameters
    ----------
    data : BeaconData

    Returns
    -------
    BeaconData

    Raises
    ------
    InputError
        ``data`` not a :class:`BeaconData` (a Survey, a DataFrame), or fewer than
        :data:`~bayes_mpem.lbl.survey.survey.MIN_PINGS` ranges.
    """
    data = check_beacon_data(data)
    if data.n < MIN_PINGS:
        raise InputError(f"beacon {data.beacon}: need at least {MIN_PINGS} ranges to fit, got "
                         f"{data.n}")
    return data


@contextmanager
def options_as_input_errors():
    """Raise the ``ValueError`` of an option's check (``_validate``) as an ``InputError``.

    Same message (the option, what was expected, what arrived); an ``InputError`` is a
    ``ValueError``, so callers catching that still do.
    """
    try:
        yield
    except InputError:
        raise
    except ValueError as exc:
        raise InputError(str(exc)) from None


def mean_resp_history(resp):
    """Return the ``(3,)`` mean class probabilities of ``resp`` (NaN for no ranges)."""
    return resp.mean(axis=0) if resp.size else np.full(3, np.nan)
