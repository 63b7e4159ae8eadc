"""Sound-speed profiles and refracted eigenrays through a layered ocean.

Conventions: depth ``z`` positive down (m), sound speed ``c`` (m/s), times in
seconds, horizontal distances in metres. A :class:`SoundSpeedProfile` is a list
of knots; between knots ``c(z)`` is linear (constant-gradient layers), above the
first and below the last knot it is constant.

Rays. In a horizontally stratified medium a ray keeps its ray parameter
``p = sin(theta) / c`` (Snell's law; ``theta`` from the vertical). In a layer
with constant gradient ``g`` the ray is a circular arc and, with
``s = cos(theta) = sqrt(1 - p**2 c**2)`` at the layer's top (0) and bottom (1),
its horizontal run and travel time have closed forms, written here without
dividing by ``g`` so that they stay exact as ``g -> 0`` (the straight segment):

* ``X = p h (c0 + c1) / (s0 + s1)``,
  ``dX/dp = h (c0 + c1) / ((s0 + s1) s0 s1)``;
* ``T = h w artanh(x) / x`` with
  ``w = (c0 + c1)(1 + s0 s1) / ((s0 + s1)(c0**2 s1**2 + c1**2))`` and
  ``x = (c1 - c0) w`` (this is ``(artanh s0 - artanh s1) / g``).

The eigenray solvers find, for every source/receiver pair at once, the ``p``
whose summed ``X`` equals the horizontal distance. ``X(p)`` increases with
``p`` up to ``1 / c_max`` (``c_max`` the fastest speed on the path, where the
ray would turn horizontal); a longer horizontal distance needs a turning point
and is reported as invalid (NaN), never approximated. The unknown is the
grazing angle ``phi`` at the fastest point, ``p = cos(phi) / c_max``, so that
both near-vertical and near-horizontal rays are resolved to full precision;
the step is Newton's (from the analytic ``dX/dp``) inside a bisection bracket.

Performance, measured on the 2-core development machine (NumPy 2.4, one
thread: elementwise operations and row sums only, no BLAS) while other jobs kept
its load average at 1.3-2.9: 10,000 direct rays from 0 m to 2,700 m through the
1,301-knot SeaGap ``ss_prof.inp`` (horizontal distances 0-8 km) take
0.23-0.48 s; the same rays reflected by the sea surface (2,700 m to 10 m)
0.28-0.32 s (the minimum of 5 runs, from several runs of)::

    import timeit, numpy as np
    from bayes_mpem.acoustics import SoundSpeedProfile, direct_ray, surface_bounce_ray
    p = SoundSpeedProfile.from_file("data/seagap/ss_prof.inp")
    h = np.linspace(0.0, 8000.0, 10000)
    min(timeit.repeat(lambda: direct_ray(p, 0.0, 2700.0, h), number=1, repeat=5))
    min(timeit.repeat(lambda: surface_bounce_ray(p, 2700.0, 10.0, h), number=1, repeat=5))

Rays go in blocks of about 2**15 array elements (rays x knots in their depth
range); the first guess, the straight chord at the harmonic-mean speed, leaves
about 2.8 Newton evaluations per ray, plus one at grazing for the validity
check and one for the travel time. Interior knots on a straight line (equal
gradients) are skipped by the tracer.

The WOA09 annual climatology (:meth:`SoundSpeedProfile.from_woa09`) is in the
source repository's ``data/woa09`` (see ``data/README.md``) and is installed with
the package; ``directory=`` or the ``BAYES_MPEM_WOA09`` environment variable
point elsewhere.
"""

from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .data import InputError

WOA09_ENV = "BAYES_MPEM_WOA09"
_EARTH_RADIUS_KM = 6371.0
_CHUNK = 1 << 15  # array elements per block of rays (keeps the temporaries in cache)


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


def _artanh_ratio(x):
    """``artanh(x) / x``, 1 at ``x = 0`` (series below ``|x| = 0.01``, error < 1e-20)."""
    x2 = x * x
    if x2.size and x2.max() < 1e-8:  # |x| < 1e-4: two terms are exact to 2e-17
        x2 *= 1 / 3
        x2 += 1.0
        return x2
    out = 1.0 + x2 * (1 / 3 + x2 * (1 / 5 + x2 * (1 / 7 + x2 / 9)))
    big = np.abs(x) >= 1e-2
    if big.any():
        out[big] = np.arctanh(x[big]) / x[big]
    return out


class SoundSpeedProfile:
    """Sound speed against depth: linear between knots, constant beyond the ends.

    Parameters
    ----------
    depth : array_like
        Knot depths (m, positive down), strictly increasing, at least one.
    speed : array_like
        Sound speed at the knots (m/s), positive.
    source : str, optional
        Where the profile came from (file, atlas cell, ...), for messages and ``repr``.

    Raises
    ------
    ValueError
        Not 1-D, different lengths, empty, a non-finite value, depths not strictly
        increasing or a speed not positive; the message names the index and value.

    Examples
    --------
    >>> prof = SoundSpeedProfile([0.0, 1000.0, 3000.0], [1520.0, 1480.0, 1510.0])
    >>> prof.speed([500.0, 4000.0]).tolist()
    [1500.0, 1510.0]
    >>> round(float(prof.harmonic_mean(0.0, 1000.0)), 3)
    1499.911
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
        bad = np.flatnonzero(np.diff(z) <= 0)
        if bad.size:
            i = bad[0] + 1
            raise ValueError(f"SoundSpeedProfile: depth[{i}] = {z[i]} is not greater than "
                             f"depth[{i - 1}] = {z[i - 1]}: depths must be strictly increasing "
                             "(positive down)")
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
        """A homogeneous medium.

        Parameters
        ----------
        c : float
            Sound speed (m/s), positive.

        Returns
        -------
        SoundSpeedProfile
            One knot at 0 m; the speed is ``c`` at every depth.

        Examples
        --------
        >>> float(SoundSpeedProfile.constant(1500.0).speed(4000.0))
        1500.0
        """
        return cls([0.0], [c], source=f"constant {c} m/s")

    @classmethod
    def from_file(cls, path, *, columns=(0, 1)) -> SoundSpeedProfile:
        """Read a two-column text profile: depth (m), sound speed (m/s).

        Fields are separated by whitespace and/or commas. Blank lines and
        everything after a ``#`` are ignored. Lines before the first data line
        whose depth or speed field is not a number are a header (column names
        such as ``depth(m) ssp(m/s)``, a title); other columns are ignored.

        Parameters
        ----------
        path : str or pathlib.Path
        columns : tuple of int, default (0, 1)
            Zero-based columns holding depth and sound speed.

        Returns
        -------
        SoundSpeedProfile

        Raises
        ------
        FileNotFoundError
        InputError
            A data line with too few fields, a field that is not a number (after
            the data began), no data at all, depths not strictly increasing or a
            speed not positive; the message names the file and line.
        """
        path = Path(path)
        ci, cj = (int(k) for k in columns)
        need = max(ci, cj) + 1
        depths, speeds, lines = [], [], []
        with path.open(encoding="utf-8-sig", errors="replace") as fh:
            for n, text in enumerate(fh, start=1):
                s = text.split("#", 1)[0].strip()
                if not s:
                    continue
                parts = [f for f in re.split(r"[,\s]+", s) if f]
                if not depths and not _numbers([parts[k] for k in (ci, cj) if k < len(parts)]):
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
                if c <= 0:
                    raise InputError(f"{path} line {n}: sound speed {c}: expected a positive "
                                     "number (m/s)")
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
        """Annual climatological profile from the World Ocean Atlas 2009 (1 degree grid).

        Takes the nearest grid cell (great-circle distance between cell centres)
        that has data, keeps its levels down to the first missing one, and
        converts ``c = 1000 + 0.01 * stored value`` (m/s).

        The copy shipped with OBSrange (``lev_latlonZ.mat``, ``lev_ann.mat``) has
        a value in every one of its 64,800 cells and 33 levels (0-5500 m), land
        included: it cannot tell where the seafloor is, so levels deeper than the
        water at the site are extrapolations. Missing values (NaN, or an integer
        fill value 0 or the type's maximum) are nevertheless handled.

        Parameters
        ----------
        lat, lon : float
            Degrees; longitude east, either -180-180 or 0-360.
        directory : str or pathlib.Path, optional
            Folder with ``lev_latlonZ.mat`` and ``lev_ann.mat`` (in the source
            repository: ``data/woa09``). Default: the ``BAYES_MPEM_WOA09``
            environment variable, else the copy installed with the package
            (or the source repository's, in a development install).
        max_distance_km : float, default 150
            Refuse a cell farther than this.

        Returns
        -------
        SoundSpeedProfile
            ``source`` names the cell and its distance.

        Raises
        ------
        FileNotFoundError
            No directory given, ``BAYES_MPEM_WOA09`` unset and no installed copy, or a
            file missing.
        InputError
            A file without the expected variables or shapes.
        ValueError
            Latitude outside [-90, 90], non-finite input, or no cell with data
            within ``max_distance_km``.
        """
        lat, lon = float(lat), float(lon)
        if not (np.isfinite(lat) and np.isfinite(lon)) or abs(lat) > 90:
            raise ValueError(f"from_woa09: expected -90 <= lat <= 90 and a finite lon, got "
                             f"lat={lat}, lon={lon}")
        if directory is None:
            directory = os.environ.get(WOA09_ENV) or _bundled_woa09()
            if not directory:
                raise FileNotFoundError(
                    "from_woa09: no WOA09 directory: pass directory=... (the folder holding "
                    "lev_latlonZ.mat and lev_ann.mat; data/woa09 in the source repository) or "
                    f"set the environment variable {WOA09_ENV}")
        glat, glon, z, c, nlev = _load_woa09(str(Path(directory).expanduser().resolve()))
        la1, la2 = np.radians(lat), np.radians(glat)
        dlon = np.radians((glon - lon) % 360.0)
        hav = np.sin((la2 - la1) / 2) ** 2 + np.cos(la1) * np.cos(la2) * np.sin(dlon / 2) ** 2
        dist = 2 * _EARTH_RADIUS_KM * np.arcsin(np.sqrt(np.clip(hav, 0.0, 1.0)))
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
            Sea pressure (dbar), strictly increasing (bin-average a cast first).
        SP : array_like
            Practical salinity.
        t : array_like
            In-situ temperature (deg C, ITS-90).
        lat, lon : float
            Position of the cast (degrees).

        Returns
        -------
        SoundSpeedProfile
            Depth ``-gsw.z_from_p(p, lat)``, speed ``gsw.sound_speed(SA, CT, p)``.

        Raises
        ------
        ImportError
            ``gsw`` is not installed.
        ValueError
            Arrays not 1-D or of different lengths, pressure not strictly
            increasing, or values for which TEOS-10 gives no speed.
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
        bad = np.flatnonzero(np.diff(p) <= 0)
        if bad.size:
            i = bad[0] + 1
            raise ValueError(f"from_ctd: pressure_dbar[{i}] = {p[i]} is not greater than "
                             f"pressure_dbar[{i - 1}] = {p[i - 1]}: expected a strictly "
                             "increasing (bin-averaged, down-cast) pressure")
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
        return self._depth.size

    def __repr__(self) -> str:
        z, c = self._depth, self._speed
        src = f", source={self.source!r}" if self.source else ""
        return (f"SoundSpeedProfile({z.size} knots, {z[0]:g}-{z[-1]:g} m, "
                f"{c.min():.2f}-{c.max():.2f} m/s{src})")

    def speed(self, z):
        """Sound speed at depth(s) ``z`` (m/s).

        Parameters
        ----------
        z : array_like
            Depth (m, positive down).

        Returns
        -------
        numpy.ndarray
            Linear between knots, constant beyond the first and last knot.
        """
        return np.interp(z, self._depth, self._speed)

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
        """Time-averaged (harmonic mean) sound speed along a vertical path.

        ``|z_bottom - z_top| / integral(dz / c)``, exact for the linear layers;
        at ``z_top == z_bottom`` the speed there.

        Parameters
        ----------
        z_top, z_bottom : array_like
            The ends of the vertical path (m), broadcast together; either order.

        Returns
        -------
        numpy.ndarray
            m/s.

        Examples
        --------
        >>> prof = SoundSpeedProfile([0.0, 100.0], [1500.0, 1510.0])
        >>> round(float(prof.harmonic_mean(0.0, 100.0)), 6)  # 100 * 0.1 / ln(1510 / 1500)
        1504.994463
        """
        zt, zb = np.broadcast_arrays(np.asarray(z_top, float), np.asarray(z_bottom, float))
        kt, rt = self._vertical_time(zt)
        kb, rb = self._vertical_time(zb)
        dt = np.abs((self._cum[kb] - self._cum[kt]) + (rb - rt))
        dz = np.abs(zb - zt)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(dz > 0, dz / dt, self.speed(zt))

    def _flat_at(self, z):
        """True where the speed is constant on both sides of depth ``z``."""
        gext = np.concatenate([[0.0], self._grad, [0.0]])
        z = np.asarray(z, float)
        right = gext[np.searchsorted(self._depth, z, side="right")]
        left = gext[np.searchsorted(self._depth, z, side="left")]
        return (right == 0) & (left == 0)


def _numbers(parts):
    try:
        [float(p) for p in parts]
    except ValueError:
        return False
    return True


@functools.lru_cache(maxsize=4)
def _bundled_woa09():
    """The atlas shipped with the package (wheel), else the source repository's copy."""
    here = Path(__file__).resolve().parent
    for d in (here / "_woa09", here.parents[1] / "data" / "woa09"):
        if (d / "lev_ann.mat").is_file() and (d / "lev_latlonZ.mat").is_file():
            return str(d)
    return None


def _load_woa09(directory: str):
    """The WOA09 grid: cell lat, lon (0-360), level depths, speeds, valid levels per cell."""
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


# --------------------------------------------------------------------------- eigenrays

@dataclass(frozen=True)
class Eigenray:
    """Eigenrays between pairs of points, one entry per pair.

    Attributes
    ----------
    time : numpy.ndarray
        One-way travel time (s); NaN where not ``valid``.
    p : numpy.ndarray
        Ray parameter ``sin(theta) / c`` (s/m), ``theta`` from the vertical.
    launch_angle, arrival_angle : numpy.ndarray
        Direction of travel at ``z_a`` and at ``z_b``, degrees from the downward
        vertical: 0 straight down, 90 horizontal, 180 straight up.
    valid : numpy.ndarray of bool
        False where no eigenray of this kind exists without a turning point.
    kind : str
        ``"direct"`` or ``"surface_bounce"``.
    """

    time: np.ndarray = field(repr=False)
    p: np.ndarray = field(repr=False)
    launch_angle: np.ndarray = field(repr=False)
    arrival_angle: np.ndarray = field(repr=False)
    valid: np.ndarray = field(repr=False)
    kind: str = "direct"


class _Legs:
    """Vertical legs ``[top, bot]`` of a block of rays, as per-ray knot arrays.

    For each leg: ``C`` (rays x knots) the speeds at the leg's knots (its ends and
    the profile knots strictly inside, the rest clipped to an end, giving layers
    of zero thickness), ``H`` the layer thicknesses, ``A = H (c0 + c1)``, and
    ``B = 1 - (c/c_max)**2`` (exactly 0 at the fastest knot), ``R2 = (c/c_max)**2``
    so that ``s = sqrt(B + R2 sin(phi)**2)`` with no cancellation at grazing.
    """

    def __init__(self, profile, legs):
        self.C, self.H = [], []
        z, c = profile._rz, profile._rc
        for top, bot in legs:
            inside = (z > top.min()) & (z < bot.max())
            zk, ck = z[inside], c[inside]
            n, m = top.size, zk.size
            t, b = top[:, None], bot[:, None]
            zc = np.empty((n, m + 2))
            zc[:, :1], zc[:, -1:] = t, b
            np.clip(zk, t, b, out=zc[:, 1:-1])
            cc = np.empty((n, m + 2))
            cc[:, 0], cc[:, -1] = profile.speed(top), profile.speed(bot)
            mid = cc[:, 1:-1]
            mid[:] = ck
            np.copyto(mid, cc[:, :1], where=zk <= t)
            np.copyto(mid, cc[:, -1:], where=zk >= b)
            self.C.append(cc)
            self.H.append(np.diff(zc, axis=1))
        self.cmax = np.max([cc.max(axis=1) for cc in self.C], axis=0)
        m = self.cmax[:, None]
        self.A, self.B, self.R2 = [], [], []
        for cc, hh in zip(self.C, self.H, strict=True):
            a = cc[:, :-1] + cc[:, 1:]
            a *= hh
            self.A.append(a)
            bb = m - cc
            bb *= m + cc
            bb *= 1.0 / (m * m)
            self.B.append(bb)
            r2 = cc * (1.0 / m)
            r2 *= r2
            self.R2.append(r2)

    def take(self, idx, names=("C", "H", "A", "B", "R2")):
        new = object.__new__(_Legs)
        for name in names:
            setattr(new, name, [a[idx] for a in getattr(self, name)])
        new.cmax = self.cmax[idx]
        return new

    def cosines(self, sin2):
        """``s = cos(theta)`` at every knot for grazing angles with ``sin(phi)**2 = sin2``."""
        out = []
        for b, r2 in zip(self.B, self.R2, strict=True):
            s = np.multiply(r2, sin2[:, None])
            s += b
            out.append(np.sqrt(s, out=s))
        return out

    def cosines_from_p(self, p):
        """``s`` at every knot for ray parameters ``p`` (0 where ``p c >= 1``)."""
        out = []
        for cc in self.C:
            pc = p[:, None] * cc
            out.append(np.sqrt(np.maximum((1.0 - pc) * (1.0 + pc), 0.0)))
        return out

    def sums(self, S, deriv=True, safe=False):
        """``sum A / (s0 + s1)`` (= X / p) and ``sum A / ((s0 + s1) s0 s1)`` (= dX/dp).

        ``safe``: count zero-thickness layers as 0 even where both their ends
        graze (``s0 = s1 = 0``, 0/0); needed only at ``p = 1 / c_max``.
        """
        x = np.zeros(S[0].shape[0])
        d = np.zeros_like(x) if deriv else None
        for a, s in zip(self.A, S, strict=True):
            s0, s1 = s[:, :-1], s[:, 1:]
            term = s0 + s1
            np.divide(a, term, out=term)
            if safe:
                term[a == 0] = 0.0
            x += term.sum(axis=1)
            if deriv:
                term /= np.multiply(s0, s1)
                d += term.sum(axis=1)
        return x, d

    def x_grazing(self):
        """``X`` at ``p = 1 / c_max`` (inf if the fastest speed holds over a finite layer)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            x, _ = self.sums(self.cosines(np.zeros(self.cmax.size)), deriv=False, safe=True)
        return x / self.cmax

    def times(self, S):
        """Travel time summed over the layers, for knot cosines ``S``."""
        t = np.zeros(S[0].shape[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            for cc, hh, s in zip(self.C, self.H, S, strict=True):
                c0, c1, s0, s1 = cc[:, :-1], cc[:, 1:], s[:, :-1], s[:, 1:]
                den = c0 * s1
                den *= den
                den += c1 * c1
                den *= s0 + s1
                w = s0 * s1
                w += 1.0
                w *= c0 + c1
                w /= den
                x = c1 - c0
                x *= w
                w *= hh
                w *= _artanh_ratio(x)
                tt = w.sum(axis=1)
                bad = np.isnan(tt)  # 0/0 of zero-thickness layers at grazing incidence
                if bad.any():
                    tt[bad] = np.where(hh[bad] > 0, w[bad], 0.0).sum(axis=1)
                t += tt
        return t


def _solve_block(legs, H, V, c_mean, tol, max_iter):
    """Grazing angle ``phi`` at the fastest point with ``X(phi) = H``; NaN where impossible."""
    n = H.size
    phi = np.full(n, np.nan)
    vertical = H == 0
    phi[vertical] = np.pi / 2
    todo = np.flatnonzero(~vertical & (V > 0))
    if todo.size:
        todo = todo[H[todo] <= legs.x_grazing()[todo]]
    if todo.size == 0:
        return phi
    sub = legs.take(todo)
    h = H[todo]
    lo = np.zeros(todo.size)             # X(lo) >= h (phi = 0: grazing)
    hi = np.full(todo.size, np.pi / 2)   # X(hi) = 0 < h (vertical)
    # phi0 from the guess c0 = c_mean: cos(phi0) = h c_max / (L c_mean), written without
    # the cancellation of arccos near 1 (exact for a homogeneous medium)
    cm, cx, v = c_mean[todo], sub.cmax, V[todo]
    x = np.arctan2(np.sqrt(np.maximum(v * v * cm * cm + h * h * (cm - cx) * (cm + cx), 0.0)),
                   h * cx)
    x = np.clip(x, 1e-150, np.pi / 2 * (1 - 1e-12))
    atol = tol * np.maximum(h, V[todo])
    idx = np.arange(todo.size)           # rows of `todo` held by `sub`
    active = np.ones(todo.size, bool)
    for _ in range(max_iter):
        sin_x, cos_x = np.sin(x), np.cos(x)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            S = sub.cosines(sin_x * sin_x)
            sx, sd = sub.sums(S)
            f = cos_x / sub.cmax * sx - h[idx]
            step = x + f / (sd * sin_x / sub.cmax)  # dX/dphi = -dX/dp sin(phi) / c_max
        lo_i = np.where(f > 0, x, lo[idx])
        hi_i = np.where(f > 0, hi[idx], x)
        done = active & ((np.abs(f) <= atol[idx])
                         | ((hi_i - lo_i) <= 4 * np.finfo(float).eps * hi_i))
        inside = (step > lo_i) & (step < hi_i)
        # converged: keep the last Newton step too (free, and squares the error)
        phi[todo[idx[done]]] = np.where(inside, step, x)[done]
        active &= ~done
        lo[idx], hi[idx] = lo_i, hi_i
        x = np.where(inside, step, 0.5 * (lo_i + hi_i))
        n_active = np.count_nonzero(active)
        if n_active == 0:
            break
        if n_active <= active.size // 2:
            sub = sub.take(active, ("A", "B", "R2"))
            idx, x, active = idx[active], x[active], np.ones(n_active, bool)
    return phi


def _as_rays(z_a, z_b, horizontal, extra=(),
             names=("z_a", "z_b", "horizontal", "plane_depth")):
    """Broadcast and flatten the inputs; check they are finite, ``horizontal >= 0``."""
    try:
        arrays = [np.asarray(v, float) for v in (z_a, z_b, horizontal, *extra)]
    except (TypeError, ValueError):
        raise ValueError(f"{', '.join(n for n in names if n)}: expected numbers or arrays of "
                         "numbers") from None
    try:
        arrays = np.broadcast_arrays(*arrays)
    except ValueError:
        raise ValueError(f"{', '.join(n for n in names if n)} must broadcast together, got "
                         f"shapes {[a.shape for a in arrays]}") from None
    flat = [a.ravel() for a in arrays]
    for name, a in zip(names, flat, strict=False):
        if not name:
            continue
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ValueError(f"{name}: expected finite numbers, got {a[bad[0]]} at flat index "
                             f"{bad[0]}")
    bad = np.flatnonzero(flat[2] < 0)
    if bad.size:
        raise ValueError(f"horizontal: expected distances >= 0 m, got {flat[2][bad[0]]} at flat "
                         f"index {bad[0]}")
    return arrays[0].shape, flat


def _trace(profile, legs, H, V, tol, max_iter):
    """Solve every ray in blocks; return ``p``, ``time`` (NaN where impossible)."""
    if not (tol > 0):
        raise ValueError(f"tol: expected a positive number, got {tol}")
    if not (isinstance(max_iter, (int, np.integer)) and max_iter >= 1):
        raise ValueError(f"max_iter: expected a positive integer, got {max_iter!r}")
    n = H.size
    p = np.full(n, np.nan)
    time = np.full(n, np.nan)
    if n == 0:
        return p, time
    deepest = np.max([b for _, b in legs], axis=0)
    shallowest = np.min([t for t, _ in legs], axis=0)
    order = np.lexsort((deepest, shallowest))
    # first guess: the straight chord in the harmonic-mean (vertical time-averaged) speed
    t_vert = 0.0
    for t, b in legs:
        kt, rt = profile._vertical_time(t)
        kb, rb = profile._vertical_time(b)
        t_vert = t_vert + ((profile._cum[kb] - profile._cum[kt]) + (rb - rt))
    with np.errstate(divide="ignore", invalid="ignore"):
        c_mean = np.where(V > 0, V / t_vert, profile.speed(shallowest))
    span = np.count_nonzero((profile._rz > shallowest.min())
                            & (profile._rz < deepest.max())) + 2
    rows = max(16, _CHUNK // (span * len(legs)))
    for start in range(0, n, rows):
        sel = order[start:start + rows]
        block = _Legs(profile, [(t[sel], b[sel]) for t, b in legs])
        phi = _solve_block(block, H[sel], V[sel], c_mean[sel], tol, max_iter)
        ok = np.isfinite(phi)
        if not ok.any():
            continue
        good = block if ok.all() else block.take(ok)
        sphi = np.sin(phi[ok])
        time[sel[ok]] = good.times(good.cosines(sphi * sphi))
        p[sel[ok]] = np.where(H[sel][ok] == 0, 0.0, np.cos(phi[ok]) / good.cmax)
    return p, time


def _angles(profile, p, z, down):
    theta = np.degrees(np.arcsin(np.minimum(p * profile.speed(z), 1.0)))
    return np.where(down, theta, 180.0 - theta)


def direct_ray(profile: SoundSpeedProfile, z_a, z_b, horizontal, *, tol: float = 1e-9,
               max_iter: int = 100) -> Eigenray:
    """Direct (non-turning) eigenray between depths ``z_a`` and ``z_b``.

    Parameters
    ----------
    profile : SoundSpeedProfile
    z_a, z_b : array_like
        Depths of the two ends (m, positive down); either may be the deeper.
    horizontal : array_like
        Horizontal distance between the ends (m, >= 0). All three broadcast.
    tol : float, default 1e-9
        Stop when the ray's horizontal run misses ``horizontal`` by at most
        ``tol * max(horizontal, |z_b - z_a|)``.
    max_iter : int, default 100
        Newton/bisection steps per ray; a ray not converged by then is invalid.

    Returns
    -------
    Eigenray
        ``time`` is symmetric in the ends. Invalid (NaN) where the horizontal
        distance needs a turning point, including ``z_a == z_b`` with
        ``horizontal > 0`` unless the speed is constant around that depth (then
        the ray is the horizontal line, ``time = horizontal / c``).

    Raises
    ------
    ValueError
        Non-finite input, negative horizontal distance, shapes that do not
        broadcast, or a non-positive ``tol``.

    Examples
    --------
    In a homogeneous medium the ray is the straight line:

    >>> ray = direct_ray(SoundSpeedProfile.constant(1500.0), 0.0, 400.0, 300.0)
    >>> round(float(ray.time * 1500.0), 9), round(float(ray.launch_angle), 4)
    (500.0, 36.8699)

    Speed falling with depth bends the ray down; a far, shallow target would need
    a turning point:

    >>> prof = SoundSpeedProfile([0.0, 1000.0], [1540.0, 1490.0])
    >>> ray = direct_ray(prof, 1000.0, [900.0, 900.0], [500.0, 5000.0])
    >>> ray.valid.tolist()
    [True, False]
    """
    shape, (za, zb, H) = _as_rays(z_a, z_b, horizontal)
    top, bot = np.minimum(za, zb), np.maximum(za, zb)
    p, time = _trace(profile, [(top, bot)], H, bot - top, tol, max_iter)
    flat = (za == zb) & (H > 0) & profile._flat_at(za)
    c = profile.speed(za[flat])
    p[flat], time[flat] = 1.0 / c, H[flat] / c
    valid = np.isfinite(time)
    down = zb >= za
    launch = np.where(valid, _angles(profile, p, za, down), np.nan)
    arrival = np.where(valid, _angles(profile, p, zb, down), np.nan)
    return Eigenray(time.reshape(shape), p.reshape(shape), launch.reshape(shape),
                    arrival.reshape(shape), valid.reshape(shape), "direct")


def surface_bounce_ray(profile: SoundSpeedProfile, z_a, z_b, horizontal, plane_depth=0.0, *,
                       tol: float = 1e-9, max_iter: int = 100) -> Eigenray:
    """Eigenray reflected once by a horizontal plane above both ends.

    The ray leaves ``z_a`` upward, reflects specularly at ``plane_depth`` and
    goes down to ``z_b``; its horizontal run is the sum of the two legs. In a
    homogeneous medium this is the image method of :mod:`bayes_mpem.geometry`:
    ``c * time == multipath_range(h, dz, d0, "double")`` with
    ``d0 = z_beacon - plane_depth``.

    Parameters
    ----------
    profile : SoundSpeedProfile
    z_a, z_b : array_like
        Depths of the two ends (m); both at or below ``plane_depth``.
    horizontal : array_like
        Horizontal distance between the ends (m, >= 0).
    plane_depth : array_like, default 0.0
        Depth of the reflector (m); 0 is the sea surface. Broadcasts with the rest.
    tol : float, default 1e-9
        Stop when the horizontal run misses by at most ``tol * max(horizontal,
        vertical path)``.
    max_iter : int, default 100

    Returns
    -------
    Eigenray
        ``launch_angle`` points up (> 90), ``arrival_angle`` down (< 90).

    Raises
    ------
    ValueError
        As :func:`direct_ray`, and an end above the plane (names the index).

    Examples
    --------
    >>> from bayes_mpem.geometry import multipath_range
    >>> ray = surface_bounce_ray(SoundSpeedProfile.constant(1500.0), 2400.0, 10.0, 3000.0)
    >>> d = float(multipath_range(3000.0, 2390.0, 2400.0, "double"))
    >>> abs(float(ray.time) * 1500.0 - d) < 1e-9
    True
    """
    shape, (za, zb, H, zp) = _as_rays(z_a, z_b, horizontal, (plane_depth,))
    bad = np.flatnonzero((za < zp) | (zb < zp))
    if bad.size:
        i = bad[0]
        raise ValueError(f"surface_bounce_ray: the reflector must be above both ends; at flat "
                         f"index {i} plane_depth = {zp[i]} m but z_a = {za[i]} m, z_b = {zb[i]} "
                         "m")
    V = (za - zp) + (zb - zp)
    p, time = _trace(profile, [(zp, za), (zp, zb)], H, V, tol, max_iter)
    flat = (V == 0) & (H > 0) & profile._flat_at(zp)
    c = profile.speed(zp[flat])
    p[flat], time[flat] = 1.0 / c, H[flat] / c
    valid = np.isfinite(time)
    launch = np.where(valid, _angles(profile, p, za, np.zeros(za.size, bool)), np.nan)
    arrival = np.where(valid, _angles(profile, p, zb, np.ones(zb.size, bool)), np.nan)
    return Eigenray(time.reshape(shape), p.reshape(shape), launch.reshape(shape),
                    arrival.reshape(shape), valid.reshape(shape), "surface_bounce")


def shoot(profile: SoundSpeedProfile, z_a, z_b, p):
    """Horizontal run and travel time of the non-turning ray with ray parameter ``p``.

    Parameters
    ----------
    profile : SoundSpeedProfile
    z_a, z_b : array_like
        Depths of the ends (m).
    p : array_like
        Ray parameter (s/m), ``0 <= p <= 1 / c_max`` with ``c_max`` the fastest
        speed between the ends. All three broadcast.

    Returns
    -------
    horizontal, time : numpy.ndarray
        m and s; NaN where ``p`` is negative or the ray would turn
        (``p c_max > 1``); inf at ``p = 1 / c_max`` when the fastest speed holds
        over a layer of finite thickness (the ray runs along it for ever).

    Raises
    ------
    ValueError
        Non-finite input or shapes that do not broadcast.

    Examples
    --------
    >>> x, t = shoot(SoundSpeedProfile.constant(1500.0), 0.0, 400.0, 0.6 / 1500.0)
    >>> round(float(x), 9), round(float(t) * 1500.0, 9)
    (300.0, 500.0)
    """
    shape, (za, zb, _, pp) = _as_rays(z_a, z_b, 0.0, (p,), ("z_a", "z_b", "", "p"))
    top, bot = np.minimum(za, zb), np.maximum(za, zb)
    x = np.full(za.size, np.nan)
    t = np.full(za.size, np.nan)
    if za.size:
        legs = _Legs(profile, [(top, bot)])
        ok = np.isfinite(pp) & (pp >= 0) & (pp * legs.cmax <= 1.0)
        if ok.any():
            sub = legs.take(ok)
            S = sub.cosines_from_p(pp[ok])
            with np.errstate(divide="ignore", invalid="ignore"):
                sx, _ = sub.sums(S, deriv=False, safe=True)
            x[ok] = np.where(bot[ok] > top[ok], pp[ok] * sx, 0.0)
            t[ok] = np.where(np.isinf(x[ok]), np.inf, sub.times(S))
    return x.reshape(shape), t.reshape(shape)
