"""Sound in the sea, shared by both problems: profiles and rays.

:class:`~bayes_mpem.acoustics.profile.SoundSpeedProfile` (a file, the WOA09
atlas, a CTD cast), eigenrays through it (:mod:`.eigenray`), turning direct
rays and surface bounces (:mod:`.turning`) and option checks
(:mod:`.profile_checks`).
"""

from .eigenray import Eigenray, direct_ray, shoot, surface_bounce_ray
from .profile import WOA09_ENV, SoundSpeedProfile

__all__ = ["WOA09_ENV", "Eigenray", "SoundSpeedProfile", "direct_ray", "shoot",
           "surface_bounce_ray"]
