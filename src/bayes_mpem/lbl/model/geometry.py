"""Straight-ray LBL geometry: direct path, image-method multipath, inversion.

Details: ``docs/model.md``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from ..._validate import check_choice
from .paths import PATHS

Path = Literal["triangle", "double"]


def check_path(path: str) -> str:
    """Return ``path`` if it is ``"triangle"`` or ``"double"``, else raise ValueError."""
    return check_choice("path", path, PATHS)


def horizontal_distance(x, y, beacon_x, beacon_y):
    """Horizontal distance between vehicle ``(x, y)`` and beacon (m)."""
    return np.hypot(np.asarray(x, float) - beacon_x, np.asarray(y, float) - beacon_y)


def direct_path(h, dz):
    """Straight line-of-sight length (m)."""
    return np.hypot(h, dz)


def reflected_leg(h, dz, d0):
    """Length ``sqrt(h**2 + (2 d0 - dz)**2)`` of one leg reflected by the plane."""
    return np.hypot(h, 2.0 * np.asarray(d0, float) - dz)


def multipath_range(h, dz, d0, path: Path = "triangle", *, direct=None):
    """Predicted one-way multipath range (m).

    Parameters
    ----------
    path : {"triangle", "double"} or array_like
        One geometry for all ranges, or one per range (names, or True for the double bounce).
    direct : array_like, optional
        Precomputed :func:`direct_path`.
    """
    refl = reflected_leg(h, dz, d0)
    if not isinstance(path, str):  # one geometry per range
        if direct is None:
            direct = direct_path(h, dz)
        return np.where(_double_mask(path), refl, 0.5 * (direct + refl))
    if path == "triangle":
        if direct is None:
            direct = direct_path(h, dz)
        return 0.5 * (direct + refl)
    if path == "double":
        return refl
    check_path(path)
    raise AssertionError("unreachable")  # pragma: no cover


def multipath_derivative(h, dz, d0, path: Path = "triangle"):
    """Differentiate :func:`multipath_range` with respect to ``d0``."""
    lever = 2.0 * np.asarray(d0, float) - dz
    d = 2.0 * lever / np.hypot(h, lever)
    if not isinstance(path, str):  # one geometry per range
        return np.where(_double_mask(path), d, 0.5 * d)
    return 0.5 * d if check_path(path) == "triangle" else d


def _double_mask(paths):
    """Boolean mask of the double bounces in an array of path names (checked), or the mask."""
    paths = np.asarray(paths)
    if paths.dtype == bool:  # already the mask (hot loops precompute it)
        return paths
    for p in np.unique(paths):
        check_path(str(p))
    return paths == "double"


def invert_plane_height(z, h, dz, path: Path = "triangle", *, direct=None):
    """Per-range plane height ``d0(k)`` that makes range ``z`` a multipath (eq. 8 of the paper).

    Returns
    -------
    numpy.ndarray
        NaN where no plane can produce the range.
    """
    z = np.asarray(z, float)
    if check_path(path) == "triangle":
        if direct is None:
            direct = direct_path(h, dz)
        refl = 2.0 * z - direct
    else:
        refl = z
    disc = refl * refl - np.asarray(h, float) ** 2
    out = np.full(np.broadcast(disc, dz).shape, np.nan)
    ok = (disc >= 0) & (refl > 0)
    out[ok] = 0.5 * (np.sqrt(disc[ok]) + np.broadcast_to(dz, out.shape)[ok])
    return out


def horizontal_slopes(h, dz, d0, path: Path = "triangle", *, direct=None):
    """Horizontal-position derivatives of the direct and multipath ranges, per unit offset.

    Returns
    -------
    slope_direct, slope_multipath : numpy.ndarray
        Times ``x - x_beacon`` (or ``y - y_beacon``): the derivative; finite at ``h = 0``.
    """
    if direct is None:
        direct = direct_path(h, dz)
    refl = reflected_leg(h, dz, d0)
    inv_d, inv_r = 1.0 / direct, 1.0 / refl
    if isinstance(path, str):
        return inv_d, (0.5 * (inv_d + inv_r) if check_path(path) == "triangle" else inv_r)
    return inv_d, np.where(_double_mask(path), inv_r, 0.5 * (inv_d + inv_r))
