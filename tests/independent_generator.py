"""Independent LBL survey generator (does not use ``bayes_mpem``).

Written from the physics and from ``docs/input.md`` only, so that diagnostics can be
checked against data that do not share the project simulator's choices. Straight rays
and one sound speed; depths positive down; every range is one-way.

* direct path: ``sqrt(h**2 + (depth - bdepth)**2)`` with ``h`` the horizontal distance;
* surface bounce off a horizontal plane at depth ``P`` (image method):
  ``sqrt(h**2 + (depth - P + bdepth - P)**2)``; ``P = 0`` (sea surface) unless drifting;
* outliers: uniform over the listening window ``[1, 1.2 * R_max]``, ``R_max`` the longest
  noise-free surface-bounce range of the survey;
* one beacon's own effects (``beacon_bias``, ``beacon_position``) act on a beacon drawn at
  random after everything else (so the other effects' draws do not change), named in
  ``truth["effect_beacon"]``.
"""
import numpy as np
import pandas as pd

MAGNITUDE_RANGES = {  # absolute value ranges; signed effects get a random sign
    "range_bias": (2.0, 15.0),  # m, added to direct and multipath ranges
    "sound_speed": (0.004, 0.02),  # f - 1, direct and multipath ranges scaled by f
    "plane_drift": (3.0, 12.0),  # m, plane depth at last ping minus at first ping
    "second_reflector": (150.0, 350.0),  # m, depth D of the second plane
    "early_outliers": (0.05, 0.2),  # fraction of replies that are (early) outliers
    "nav_drift": (10.0, 60.0),  # m, horizontal navigation error at the last ping
    "beacon_bias": (2.0, 15.0),  # m, added to one beacon's direct and multipath ranges
    "beacon_position": (10.0, 60.0),  # m, horizontal error of one beacon's reported position
}
SIGNED = {"range_bias", "sound_speed", "plane_drift", "beacon_bias"}
PER_BEACON = {"beacon_bias", "beacon_position"}


def draw_magnitude(name, rng):
    """One realistic magnitude of effect ``name``: uniform in ``|m|``, random sign if signed."""
    lo, hi = MAGNITUDE_RANGES[name]
    m = rng.uniform(lo, hi)
    return float(-m if (name in SIGNED and rng.random() < 0.5) else m)


def _place_beacons(rng, n):
    """Irregular layout: each beacon 3-5 km from an earlier one, every pair >= 3 km apart."""
    pts = [rng.uniform(-1000.0, 1000.0, 2)]
    while len(pts) < n:
        base = pts[rng.integers(len(pts))]
        ang, dist = rng.uniform(0, 2 * np.pi), rng.uniform(3000.0, 5000.0)
        cand = base + dist * np.array([np.cos(ang), np.sin(ang)])
        if all(np.hypot(*(cand - p)) >= 3000.0 for p in pts):
            pts.append(cand)
    return np.array(pts)


def _track(rng, times, centre, radius):
    """True horizontal track: alternating straight transits, circles and a random walk."""
    xy = np.empty((len(times), 2))
    pos = centre + rng.uniform(-0.3, 0.3, 2) * radius
    heading, speed = rng.uniform(0, 2 * np.pi), rng.uniform(1.0, 2.0)
    mode, seg_end, turn, goal = None, -np.inf, 0.0, None
    for i, t in enumerate(times):
        if t >= seg_end:  # start a new segment of 10-60 min
            mode = rng.choice(["transit", "circle", "walk"])
            seg_end, speed = t + rng.uniform(600.0, 3600.0), rng.uniform(1.0, 2.0)
            goal = None
            turn = rng.choice([-1.0, 1.0]) * speed / rng.uniform(200.0, 800.0)  # rad/s
        if goal is None or np.hypot(*(goal - pos)) < 100.0:  # next waypoint of the transit
            r, a = radius * np.sqrt(rng.random()), rng.uniform(0, 2 * np.pi)
            goal = centre + r * np.array([np.cos(a), np.sin(a)])
        dt = t - times[i - 1] if i else 0.0
        off = pos - centre
        if np.hypot(*off) > 1.2 * radius:  # too far out: head back whatever the mode
            dh = np.angle(np.exp(1j * (np.arctan2(-off[1], -off[0]) - heading)))
        elif mode == "transit":
            dh = np.angle(np.exp(1j * (np.arctan2(*(goal - pos)[::-1]) - heading)))
        elif mode == "circle":
            dh = turn * dt
        else:
            dh = rng.normal(0.0, 0.02 * np.sqrt(dt))
        dh = np.clip(dh, -0.05 * dt, 0.05 * dt)  # finite turn rate
        pos = pos + speed * dt * np.array([np.cos(heading + dh / 2), np.sin(heading + dh / 2)])
        heading += dh
        xy[i] = pos
    return xy


def _image(h, depth, bdepth, plane):
    """Image-method length of a bounce off a horizontal plane at depth ``plane``."""
    return np.sqrt(h**2 + (depth - plane + bdepth - plane) ** 2)


def generate(effect=None, magnitude=None, *, seed, n_ranges=5000, n_beacons=4,
             second_effect=None, second_magnitude=None):
    """Simulate one survey; returns ``{"pings", "beacons", "truth"}`` (see module docstring).

    ``effect``/``second_effect`` are keys of ``MAGNITUDE_RANGES`` (or None); a magnitude of
    None is drawn with :func:`draw_magnitude`. ``pings`` has one row per interrogation
    (``n_ranges`` rows, empty ``range`` = no reply); ``truth["labels"]`` gives each row's
    class (``dp``, ``mp``, ``mp2``, ``ol``, ``no_reply``).
    """
    rng = np.random.default_rng(seed)
    effects = {}  # name -> magnitude actually used
    for name, mag in ((effect, magnitude), (second_effect, second_magnitude)):
        if name is None:
            continue
        if name not in MAGNITUDE_RANGES or name in effects:
            raise ValueError(f"unknown or repeated effect {name!r}")
        effects[name] = float(draw_magnitude(name, rng) if mag is None else mag)
    requested = dict(effects)
    ids = [chr(ord("A") + k) for k in range(n_beacons)]
    bxy = _place_beacons(rng, n_beacons)
    centre = bxy.mean(axis=0)
    radius = max(1500.0, 0.6 * np.max(np.hypot(*(bxy - centre).T)))
    z0, grad = rng.uniform(1400.0, 3600.0), rng.uniform(-0.03, 0.03, 2)

    def seafloor(p):
        return np.clip(z0 + (p - centre) @ grad, 1000.0, 4000.0)

    bdepth = seafloor(bxy) - rng.uniform(0.0, 5.0, n_beacons)  # moored just above the floor
    times = rng.uniform(0.0, 86400.0) + np.cumsum(rng.uniform(3.0, 15.0, n_ranges))
    xy = _track(rng, times, centre, radius)
    knots = np.linspace(times[0], times[-1], max(3, int((times[-1] - times[0]) / 3600) + 2))
    altitude = np.interp(times, knots, rng.uniform(50.0, 400.0, len(knots)))
    depth = seafloor(xy) - altitude
    order = np.concatenate([rng.permutation(n_beacons) for _ in range(n_ranges // n_beacons + 1)])
    b = order[:n_ranges]  # beacons interrogated in a random order within each cycle

    frac = (times - times[0]) / (times[-1] - times[0])
    plane = effects.get("plane_drift", 0.0) * frac  # surface plane depth over time
    h = np.hypot(*(xy - bxy[b]).T)
    r_dp = np.hypot(h, depth - bdepth[b])
    r_mp = _image(h, depth, bdepth[b], plane)
    r_max = float(np.max(_image(h, depth, bdepth[b], min(0.0, plane.min()))))
    window = (1.0, 1.2 * r_max)

    sig_dp, sig_mp = rng.uniform(1.0, 5.0, n_beacons), rng.uniform(3.0, 15.0, n_beacons)
    w_mp, w_ol = rng.uniform(0.15, 0.4, n_beacons), rng.uniform(0.03, 0.15, n_beacons)
    w_mp2, sig_mp2 = np.zeros(n_beacons), np.full(n_beacons, np.nan)
    p_noreply = rng.uniform(0.0, 0.1, n_beacons)
    if "second_reflector" in effects:
        d2 = effects["second_reflector"]
        if not 0.0 < d2 < depth.min():
            raise ValueError(f"second plane at {d2} m is not above the vehicle "
                             f"(shallowest {depth.min():.0f} m)")
        w_mp2, sig_mp2 = rng.uniform(0.1, 0.25, n_beacons), rng.uniform(3.0, 15.0, n_beacons)
    if "early_outliers" in effects:
        w_ol = np.full(n_beacons, effects["early_outliers"])
    w_dp = 1.0 - w_mp - w_mp2 - w_ol

    reply = rng.random(n_ranges) >= p_noreply[b]
    probs = np.stack([w_dp, w_mp, w_mp2, w_ol], axis=1)[b]
    if "early_outliers" in effects:  # exactly the requested fraction of replies
        idx = np.flatnonzero(reply)
        is_ol = np.zeros(n_ranges, bool)
        n_ol = int(round(effects["early_outliers"] * len(idx)))
        is_ol[rng.choice(idx, n_ol, replace=False)] = True
        probs[:, 3] = is_ol
        probs[~is_ol, :3] /= probs[~is_ol, :3].sum(axis=1, keepdims=True)
        probs[is_ol, :3] = 0.0
        effects["early_outliers"] = float(is_ol.sum() / len(idx))  # the fraction generated
    cls = (rng.random(n_ranges)[:, None] > np.cumsum(probs, axis=1)).sum(axis=1)
    cls = np.minimum(cls, 3)

    f = 1.0 + effects.get("sound_speed", 0.0)
    bias = effects.get("range_bias", 0.0)
    rng_ = np.full(n_ranges, np.nan)
    for k, (geom, sig) in enumerate([(r_dp, sig_dp), (r_mp, sig_mp)]):
        m = cls == k
        rng_[m] = f * geom[m] + bias + rng.normal(0.0, sig[b[m]])
    m = cls == 2
    if m.any():
        r_mp2 = _image(h[m], depth[m], bdepth[b[m]], effects["second_reflector"])
        rng_[m] = f * r_mp2 + bias + rng.normal(0.0, sig_mp2[b[m]])
    m = cls == 3
    hi = f * r_dp[m] + bias if "early_outliers" in effects else window[1]
    rng_[m] = rng.uniform(window[0], np.maximum(hi, window[0] + 1.0), size=int(m.sum()))
    target = None
    if PER_BEACON & set(effects):  # drawn last: the other draws stay as they were
        target = int(rng.integers(n_beacons))
        m = (b == target) & (cls <= 2)
        rng_[m] += effects.get("beacon_bias", 0.0)
    n_clipped = int(np.sum(rng_ < 0.1))
    rng_ = np.where(rng_ < 0.1, 0.1, rng_)
    rng_[~reply] = np.nan
    labels = np.where(reply, np.array(["dp", "mp", "mp2", "ol"])[cls], "no_reply")

    direction = rng.uniform(0, 2 * np.pi) if "nav_drift" in effects else None
    nav = xy.copy()
    if direction is not None:
        nav += effects["nav_drift"] * frac[:, None] * [np.cos(direction), np.sin(direction)]
    pings = pd.DataFrame({"time": times, "beacon": np.array(ids)[b], "range": rng_,
                          "x": nav[:, 0], "y": nav[:, 1], "depth": depth})
    reported = bxy.copy()
    if "beacon_position" in effects:  # the table puts the beacon this far off, horizontally
        ang = rng.uniform(0, 2 * np.pi)
        reported[target] += effects["beacon_position"] * np.array([np.cos(ang), np.sin(ang)])
    beacons = pd.DataFrame({"beacon": ids, "x": reported[:, 0], "y": reported[:, 1],
                            "depth": bdepth})
    per = lambda a: {i: float(v) for i, v in zip(ids, a, strict=True)}  # noqa: E731
    realised = {i: {c: float(np.mean(labels[reply & (b == k)] == c))
                    for c in ("dp", "mp", "mp2", "ol")} for k, i in enumerate(ids)}
    truth = {
        "effect": effect, "magnitude": effects.get(effect),
        "second_effect": second_effect, "second_magnitude": effects.get(second_effect),
        "effects": effects, "requested": requested, "seed": seed,
        "d0": per(bdepth - plane[0]), "plane_depth_first": float(plane[0]),
        "plane_depth_last": float(plane[-1]),
        "sigma_dp": per(sig_dp), "sigma_mp": per(sig_mp), "sigma_mp2": per(sig_mp2),
        "weights": {i: {"dp": float(w_dp[k]), "mp": float(w_mp[k]), "mp2": float(w_mp2[k]),
                        "ol": float(w_ol[k])} for k, i in enumerate(ids)},
        "realised_weights": realised, "no_reply_prob": per(p_noreply),
        "outlier_fraction": float(np.mean(labels[reply] == "ol")),
        "sound_speed_factor": f, "range_bias": bias, "window": window,
        "second_plane_depth": effects.get("second_reflector"),
        "nav_drift_direction": direction,  # radians from +x, counter-clockwise
        "labels": labels, "true_x": xy[:, 0], "true_y": xy[:, 1],
        "seafloor_z0": float(z0), "seafloor_gradient": grad.tolist(), "n_clipped": n_clipped,
        "effect_beacon": None if target is None else ids[target],
    }
    return {"pings": pings, "beacons": beacons, "truth": truth}


def _check(out):
    """Assert the tables follow docs/input.md; returns the pings table."""
    p, bcn = out["pings"], out["beacons"]
    assert list(p.columns) == ["time", "beacon", "range", "x", "y", "depth"]
    assert list(bcn.columns) == ["beacon", "x", "y", "depth"] and bcn.beacon.is_unique
    assert np.isfinite(p[["time", "x", "y", "depth"]].to_numpy()).all()
    assert np.isfinite(bcn[["x", "y", "depth"]].to_numpy()).all()
    assert (p["range"].dropna() > 0).all() and np.all(np.diff(p.time) > 0)
    assert set(p.beacon) <= set(bcn.beacon) and (p.depth > 0).all()
    return p


if __name__ == "__main__":
    import tempfile
    from pathlib import Path

    out_dir = Path(tempfile.mkdtemp(prefix="indep_gen_"))
    for k, name in enumerate([None, *MAGNITUDE_RANGES]):
        out = generate(name, seed=100 + k)
        p = _check(out)
        tag = name or "clean"
        p.to_csv(out_dir / f"{tag}_pings.csv", index=False)
        out["beacons"].to_csv(out_dir / f"{tag}_beacons.csv", index=False)
        back = pd.read_csv(out_dir / f"{tag}_pings.csv", dtype={"beacon": str})
        assert back["range"].isna().sum() == p["range"].isna().sum()
        t = out["truth"]
        lab = pd.Series(t["labels"]).value_counts().to_dict()
        print(f"{tag:17s} mag={t['magnitude']!s:>22.22s} rows={len(p)} "
              f"depth={p.depth.min():.0f}-{p.depth.max():.0f} m "
              f"range<={p['range'].max():.0f} m {lab}")
    two = generate("range_bias", 8.0, seed=7, second_effect="nav_drift", second_magnitude=30.0)
    _check(two)
    print("two effects:", two["truth"]["effects"], "->", out_dir)
