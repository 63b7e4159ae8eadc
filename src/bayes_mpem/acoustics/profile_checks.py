"""Checks of a profile and a nominal sound speed before rays are traced through them."""

from __future__ import annotations

from .._validate import check_positive
from .profile import SoundSpeedProfile

# --------------------------------------------------------------------------- checks

def check_profile(ssp, deepest: float | None = None, *, name: str = "ssp") -> SoundSpeedProfile:
    """Validate a sound-speed profile for ranges down to ``deepest``.

    A profile of several knots must reach ``deepest`` (below its last knot the speed would be
    an extrapolation); a one-knot profile is homogeneous and accepted at any depth.

    Parameters
    ----------
    deepest : float, optional
        The deepest beacon or vehicle (m).
    name : str
        Argument name used in messages.

    Raises
    ------
    TypeError, ValueError
    """
    if not isinstance(ssp, SoundSpeedProfile):
        raise TypeError(f"{name}: expected a SoundSpeedProfile (bayes_mpem.acoustics), got "
                        f"{type(ssp).__name__}")
    if deepest is not None and len(ssp) > 1 and float(ssp.depths[-1]) < float(deepest):
        raise ValueError(
            f"{name}: the profile ends at {ssp.depths[-1]:g} m but the rays reach "
            f"{float(deepest):g} m (deepest beacon or vehicle); extend it below the beacons "
            "(e.g. SoundSpeedProfile.from_woa09) or pass SoundSpeedProfile.constant(c)"
            + (f" [{ssp.source}]" if ssp.source else ""))
    return ssp


def check_sound_speed(sound_speed, name: str = "sound_speed") -> float:
    """``sound_speed`` as a float, if it is a plausible speed (m/s); else ValueError."""
    return check_positive(name, sound_speed, what="a positive sound speed in m/s")


def nominal_sound_speed(ssp: SoundSpeedProfile, depth) -> float:
    """Harmonic-mean sound speed from the sea surface down to ``depth`` (m/s).

    Parameters
    ----------
    depth : float
        m, positive down.
    """
    return float(ssp.harmonic_mean(0.0, float(depth)))
