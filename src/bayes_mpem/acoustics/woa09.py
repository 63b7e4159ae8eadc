"""The World Ocean Atlas 2009 annual sound-speed climatology: locating and loading it."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ..exceptions import InputError


def number_parts(parts):
    """Tell whether every string of ``parts`` parses as a number."""
    try:
        [float(p) for p in parts]
    except ValueError:
        return False
    return True


@functools.lru_cache(maxsize=4)
def bundled_woa09():
    """Find the WOA09 atlas: the package's copy (wheel), else the source repository's.

    Returns
    -------
    str or None
        The folder holding ``lev_ann.mat`` and ``lev_latlonZ.mat``; None if neither has them.
    """
    here = Path(__file__).resolve().parents[1]  # the bayes_mpem package
    for d in (here / "_woa09", here.parents[1] / "data" / "woa09"):
        if (d / "lev_ann.mat").is_file() and (d / "lev_latlonZ.mat").is_file():
            return str(d)
    return None


def load_woa09(directory: str):
    """Load the WOA09 grid from ``directory``.

    Returns
    -------
    tuple
        Cell latitudes, longitudes (0-360), level depths, speeds, valid levels per cell.

    Raises
    ------
    FileNotFoundError
    """
    from scipy.io import loadmat

    d = Path(directory)
    grid_file, ann_file = d / "lev_latlonZ.mat", d / "lev_ann.mat"
    for f in (grid_file, ann_file):
        if not f.is_file():
            raise FileNotFoundError(f"from_woa09: {f} not found (expected lev_latlonZ.mat and "
                                    f"lev_ann.mat in {d})")
    grid, ann = loadmat(grid_file), loadmat(ann_file)
    for f, m, keys in ((grid_file, grid, ("lat", "lon", "z")), (ann_file, ann, ("c",))):
        missing = [k for k in keys if k not in m]
        if missing:
            raise InputError(f"{f}: expected variables {keys}, missing {missing}")
    lat = grid["lat"].ravel() / 10.0
    lon = (grid["lon"].ravel() / 10.0) % 360.0
    z = grid["z"].ravel().astype(float)
    raw = ann["c"]
    if raw.shape != (lat.size, z.size) or lon.size != lat.size:
        raise InputError(f"{ann_file}: expected c of shape ({lat.size}, {z.size}) (cells x "
                         f"levels of {grid_file.name}), got {raw.shape}")
    c = 1000.0 + 0.01 * raw.astype(float)
    ok = np.isfinite(c)
    if np.issubdtype(raw.dtype, np.integer):
        ok &= (raw != 0) & (raw != np.iinfo(raw.dtype).max)
    nlev = np.where(ok.all(axis=1), z.size, np.argmin(ok, axis=1))
    for a in (lat, lon, z, c, nlev):
        a.setflags(write=False)
    return lat, lon, z, c, nlev
