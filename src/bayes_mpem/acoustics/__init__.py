"""Sound in the sea, shared by both problems: profiles and rays."""

from .eigenray import Eigenray, direct_ray, shoot, surface_bounce_ray
from .profile import WOA09_ENV, SoundSpeedProfile

__all__ = ["WOA09_ENV", "Eigenray", "SoundSpeedProfile", "direct_ray", "shoot",
           "surface_bounce_ray"]
