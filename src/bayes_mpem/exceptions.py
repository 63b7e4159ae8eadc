"""Every public exception and warning class of the package."""

from __future__ import annotations


class InputError(ValueError):
    """Invalid user input (pings/beacons tables or arrays); the message says where and why."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C after part of a run's results were kept; the message says which (``batch``)."""


class ConvergenceWarning(UserWarning):
    """An EM run stopped at ``max_iter`` before meeting its stopping rule."""


class FitQualityWarning(UserWarning):
    """A fit converged to something that is not a credible reflector (see ``EMResult.flags``)."""


class SamplingWarning(UserWarning):
    """The chain hit its step cap before it was ``tau_factor`` autocorrelation times long."""


class UnusableStartError(ValueError):
    """The EM solution the walkers would start from lies outside the prior, or is flagged."""


class SkippedBeaconWarning(UserWarning):
    """A beacon has too few replies to fit and is left unfitted."""


class LocateWarning(UserWarning):
    """A location fit is poorly constrained or did not converge."""


class PathChoiceWarning(FitQualityWarning):
    """A forced multipath geometry fits clearly worse than the other one (see ``path="auto"``)."""


class ModelCheckWarning(FitQualityWarning):
    """The ranges depart from the fitted model in a way its checks see (``bayes-mpem diagnose``)."""
class NavigationWarning(UserWarning):
    """Part of a navigated track (or a dead-reckoning nuisance) is not corrected by the ranges."""
