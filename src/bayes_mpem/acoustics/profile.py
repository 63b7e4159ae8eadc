"""Sound-speed profiles: speed against depth in constant-gradient layers."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .._validate import check_increasing
from ..exceptions import InputError
from ..io.boundary import limit_problem, read_text_lines
from ..io.geodesy import MEAN_EARTH_RADIUS_KM
from .woa09 import bundled_woa09, load_woa09, number_parts

WOA09_ENV = "BAYES_MPEM_WOA09"


# --------------------------------------------------------------------------- profile

def _as_1d(values, name):
    try:
        arr = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"SoundSpeedProfile: {name}: expected a 1-D sequence of numbers, "
                         f"got {values!r:.60}") from None
    if arr.ndim != 1:
        raise ValueError(f"SoundSpeedProfile: {name}: expected a 1-D sequence, got shape "
                         f"{arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"SoundSpeedProfile: {name}[{bad[0]}] = {arr[bad[0]]}: expected a "
                         "finite number")
    return arr


def _log1p_ratio(u):
    """``log1p(u) / u``, 1 at ``u = 0`` (no cancellation for tiny ``u``)."""
    u = np.asarray(u, float)
    small = np.abs(u) < 1e-6
    safe = np.where(small, 1.0, u)
    return np.where(small, 1.0 - u / 2.0 + u * u / 3.0, np.log1p(safe) / safe)


class SoundSpeedProfile:
    """Sound speed against depth: linear between knots, constant beyond the ends.

    Parameters
    ----------
    depth : array_like
        Knot depths (m, positive down), strictly increasing, at least one.
    speed : array_like
        Sound speed at the knots (m/s), positive.
    source : str, optional
        Where the profile came from, for messages and ``repr``.

    Raises
    ------
    ValueError
        A bad shape or value (the message names the index and value).
    """

    __slots__ = ("_depth", "_speed", "_grad", "_cum", "_rz", "_rc", "source")

    def __init__(self, depth, speed, *, source: str = ""):
        z = _as_1d(depth, "depth")
        c = _as_1d(speed, "speed")
        if z.size != c.size:
            raise ValueError(f"SoundSpeedProfile: depth and speed must have the same length, "
                             f"got {z.size} and {c.size}")
        if z.size == 0:
            raise ValueError("SoundSpeedProfile: expected at least one knot, got none")
        check_increasing("depth", z, context="SoundSpeedProfile: ",
                         what="strictly increasing depths (positive down)")
        bad = np.flatnonzero(c <= 0)
        if bad.size:
            raise ValueError(f"SoundSpeedProfile: speed[{bad[0]}] = {c[bad[0]]}: expected a "
                             "positive sound speed (m/s)")
        h = np.diff(z)
        grad = np.diff(c) / h
        # vertical slowness integral from the first knot to every knot
        layer = h / c[:-1] * _log1p_ratio(np.diff(c) / c[:-1])
        cum = np.concatenate([[0.0], np.cumsum(layer)])
        # knots the ray tracer needs: drop interior knots on a straight line (same gradient
        # on both sides to 1e-12 relative), which changes the medium by nothing
        same = np.abs(np.diff(grad)) <= 1e-12 * np.maximum(np.abs(grad[1:]), np.abs(grad[:-1]))
        keep = np.concatenate([[True], ~same, [True]]) if z.size > 1 else np.ones(1, bool)
        rz, rc = z[keep], c[keep]
        for a in (z, c, grad, cum, rz, rc):
            a.setflags(write=False)
        self._depth, self._speed, self._grad, self._cum = z, c, grad, cum
        self._rz, self._rc = rz, rc
        self.source = str(source)

    # ----------------------------------------------------------------- constructors
    @classmethod
    def constant(cls, c: float) -> SoundSpeedProfile:
        """Make a homogeneous medium of speed ``c`` (m/s).

        Parameters
        ----------
        c : float

        Returns
        -------
        SoundSpeedProfile
        """
        return cls([0.0], [c], source=f"constant {c} m/s")

    @classmethod
    def from_file(cls, path, *, columns=(0, 1)) -> SoundSpeedProfile:
        """Read a text profile: depth (m), sound speed (m/s); ``#`` comments and a header allowed.

        Parameters
        ----------
        path : str or pathlib.Path
        columns : tuple of int, default (0, 1)
            Zero-based columns of depth and sound speed.

        Raises
        ------
        FileNotFoundError, InputError
            No file; a bad line or profile (naming the file and line).
        """
        path = Path(path)
        ci, cj = (int(k) for k in columns)
        need = max(ci, cj) + 1
        depths, speeds, lines = [], [], []
        for n, text in enumerate(read_text_lines(path, "sound-speed profile"), start=1):
            s = text.split("#", 1)[0].strip()
            if not s:
                continue
            parts = [f for f in re.split(r"[,\s]+", s) if f]
            if not depths and not number_parts([parts[k] for k in (ci, cj) if k < len(parts)]):
                continue  # header (column names, units, a title) before the data
            if len(parts) < need:
                raise InputError(f"{path} line {n}: expected at least {need} fields (depth "
                                 f"in column {ci}, speed in column {cj}, counting from 0), "
                                 f"got {len(parts)}: {text.strip()!r}")
            try:
                z, c = float(parts[ci]), float(parts[cj])
            except ValueError:
                raise InputError(f"{path} line {n}: expected numbers in columns {ci} and {cj} "
                                 f"(depth, sound speed), got {text.strip()!r}") from None
            if not (np.isfinite(z) and np.isfinite(c)):
                raise InputError(f"{path} line {n}: expected finite numbers, got "
                                 f"{text.strip()!r}")
            if depths and z <= depths[-1]:
                raise InputError(f"{path} line {n}: depth {z} is not greater than the "
                                 f"previous depth {depths[-1]} (line {lines[-1]}): depths "
                                 "must be strictly increasing (positive down)")
            why = limit_problem("sound_speed", c) or limit_problem("depth", z)
            if why:
                raise InputError(f"{path} line {n}: {why}: expected a physically possible "
                                 "sea-water profile (depth m, sound speed m/s)")
            depths.append(z)
            speeds.append(c)
            lines.append(n)
        if not depths:
            raise InputError(f"{path}: no data lines found (expected depth and sound speed "
                             "columns)")
        return cls(depths, speeds, source=str(path))

    @classmethod
    def from_woa09(cls, lat: float, lon: float, directory=None, *,
                   max_distance_km: float = 150.0) -> SoundSpeedProfile:
        """Annual climatological profile of the nearest World Ocean Atlas 2009 cell (1 degree).

        The atlas has no seafloor: levels deeper than the water at the site are extrapolations.

        Parameters
        ----------
        lat, lon : float
            Degrees; longitude east, either -180-180 or 0-360.
        directory : str or pathlib.Path, optional
            Folder with ``lev_latlonZ.mat`` and ``lev_ann.mat``; default ``$BAYES_MPEM_WOA09``,
            else the copy installed with the package.
        max_distance_km : float, default 150
            Refuse a cell farther than this.

        Raises
        ------
        FileNotFoundError, InputError, ValueError
            No atlas; an atlas file not as expected; bad input or no cell within reach.
        """
        lat, lon = float(lat), float(lon)
        if not (np.isfinite(lat) and np.isfinite(lon)) or abs(lat) > 90:
            raise ValueError(f"from_woa09: expected -90 <= lat <= 90 and a finite lon, got "
                             f"lat={lat}, lon={lon}")
        if directory is None:
            directory = os.environ.get(WOA09_ENV) or bundled_woa09()
            if not directory:
                raise FileNotFoundError(
                    "from_woa09: no WOA09 directory: pass directory=... (the folder holding "
                    "lev_latlonZ.mat and lev_ann.mat; data/woa09 in the source repository) or "
                    f"set the environment variable {WOA09_ENV}")
        glat, glon, z, c, nlev = load_woa09(str(Path(directory).expanduser().resolve()))
        la1, la2 = np.radians(lat), np.radians(glat)
        dlon = np.radians((glon - lon) % 360.0)
        hav = np.sin((la2 - la1) / 2) ** 2 + np.cos(la1) * np.cos(la2) * np.sin(dlon / 2) ** 2
        dist = 2 * MEAN_EARTH_RADIUS_KM * np.arcsin(np.sqrt(np.clip(hav, 0.0, 1.0)))
        dist = np.where(nlev > 0, dist, np.inf)
        k = int(np.argmin(dist))
        if not dist[k] <= max_distance_km:
            near = "no cell has data" if not np.isfinite(dist[k]) else (
                f"the nearest cell with data, ({glat[k]}, {glon[k]}), is {dist[k]:.0f} km away")
            raise ValueError(f"from_woa09: no WOA09 cell with data within {max_distance_km} km "
                             f"of lat={lat}, lon={lon}: {near}")
        n = int(nlev[k])
        return cls(z[:n], c[k, :n], source=f"WOA09 annual, cell ({glat[k]:g}, {glon[k]:g}), "
                   f"{dist[k]:.1f} km from ({lat:g}, {lon:g})")

    @classmethod
    def from_ctd(cls, pressure_dbar, SP, t, lat: float, lon: float) -> SoundSpeedProfile:
        """Sound speed from a CTD cast with TEOS-10 (the optional ``gsw`` package).

        Parameters
        ----------
        pressure_dbar : array_like
            Sea pressure (dbar), strictly increasing.
        SP, t : array_like
            Practical salinity and in-situ temperature (deg C, ITS-90).
        lat, lon : float

        Returns
        -------
        SoundSpeedProfile

        Raises
        ------
        ImportError, ValueError
            ``gsw`` not installed; bad arrays, or values TEOS-10 gives no speed for.
        """
        try:
            import gsw
        except ImportError as exc:
            raise ImportError("SoundSpeedProfile.from_ctd needs the TEOS-10 package gsw: "
                              "pip install gsw") from exc
        p = _as_1d(pressure_dbar, "pressure_dbar")
        sp = _as_1d(SP, "SP")
        temp = _as_1d(t, "t")
        if not p.size == sp.size == temp.size:
            raise ValueError(f"from_ctd: pressure_dbar, SP and t must have the same length, got "
                             f"{p.size}, {sp.size} and {temp.size}")
        check_increasing("pressure_dbar", p, context="from_ctd: ",
                         what="a strictly increasing (bin-averaged, down-cast) pressure")
        sa = gsw.SA_from_SP(sp, p, lon, lat)
        ct = gsw.CT_from_t(sa, temp, p)
        c = np.asarray(gsw.sound_speed(sa, ct, p), float)
        depth = -np.asarray(gsw.z_from_p(p, lat), float)
        return cls(depth, c, source=f"CTD at ({lat:g}, {lon:g}), TEOS-10 (gsw)")

    # ----------------------------------------------------------------- queries
    @property
    def depths(self) -> np.ndarray:
        """Knot depths (m), read-only."""
        return self._depth

    @property
    def speeds(self) -> np.ndarray:
        """Knot sound speeds (m/s), read-only."""
        return self._speed

    def __len__(self) -> int:
        """Return the number of knots."""
        return self._depth.size

    def __repr__(self) -> str:
        """Short summary (sizes and source), not the data."""
        z, c = self._depth, self._speed
        src = f", source={self.source!r}" if self.source else ""
        return (f"SoundSpeedProfile({z.size} knots, {z[0]:g}-{z[-1]:g} m, "
                f"{c.min():.2f}-{c.max():.2f} m/s{src})")

    def speed(self, z):
        """Sound speed (m/s) at depth(s) ``z`` (m).

        Parameters
        ----------
        z : array_like

        Returns
        -------
        numpy.ndarray
        """
        return np.interp(z, self._depth, self._speed)

    @property
    def ray_knots(self) -> tuple[np.ndarray, np.ndarray]:
        """Depths and speeds of the knots a ray tracer needs (collinear ones dropped)."""
        return self._rz, self._rc

    def vertical_time(self, z_top, z_bottom):
        """Signed one-way vertical travel time from ``z_top`` to ``z_bottom`` (s).

        Parameters
        ----------
        z_top, z_bottom : array_like

        Returns
        -------
        numpy.ndarray
        """
        kt, rt = self._vertical_time(z_top)
        kb, rb = self._vertical_time(z_bottom)
        return (self._cum[kb] - self._cum[kt]) + (rb - rt)

    def _vertical_time(self, z):
        """``(k, r)``: the vertical time from the first knot to ``z`` is ``cum[k] + r``."""
        z = np.asarray(z, float)
        zk, ck = self._depth, self._speed
        k = np.clip(np.searchsorted(zk, z, side="right") - 1, 0, zk.size - 1)
        g = np.append(self._grad, 0.0)[k]
        dz = z - zk[k]
        g = np.where(dz < 0, 0.0, g)  # above the first knot: constant speed
        return k, dz / ck[k] * _log1p_ratio(g * dz / ck[k])

    def harmonic_mean(self, z_top, z_bottom):
        """Harmonic-mean (time-averaged) sound speed (m/s) along a vertical path, either order.

        Parameters
        ----------
        z_top, z_bottom : array_like

        Returns
        -------
        numpy.ndarray
        """
        zt, zb = np.broadcast_arrays(np.asarray(z_top, float), np.asarray(z_bottom, float))
        dt = np.abs(self.vertical_time(zt, zb))
        dz = np.abs(zb - zt)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(dz > 0, dz / dt, self.speed(zt))

    def flat_at(self, z):
        """Tell where the speed is constant on both sides of depth ``z``.

        Parameters
        ----------
        z : array_like

        Returns
        -------
        ndarray of bool
        """
        gext = np.concatenate([[0.0], self._grad, [0.0]])
        z = np.asarray(z, float)
        right = gext[np.searchsorted(self._depth, z, side="right")]
        left = gext[np.searchsorted(self._depth, z, side="left")]
        return (right == 0) & (left == 0)
