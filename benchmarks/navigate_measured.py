"""Navigation on measured surveys: real ranges, a GPS truth, a dead reckoning made from it.

Run from the repository root::

    python benchmarks/navigate_measured.py           # writes its section of docs/navigate.md
    python benchmarks/navigate_measured.py --quick   # 2 seeds, prints only
    python benchmarks/navigate_measured.py --ray-only  # the SeaGap ray-traced table alone
    python benchmarks/navigate_measured.py --why       # what the ray-traced coverage lacks

The surveys are the bundled SeaGap GNSS-acoustic example (a ship over four
transponders at known positions, ``pxp-ini.inp``; 3,347 ranges in 859 shots over
14.6 h) and the OBSrange surveys SIO CC03 and WHOI S05 (a ship circling one
ocean-bottom seismometer). The ship's GPS track (SeaGap: the transducer, moved
from the antenna by the lever arm) is the truth. A dead reckoning is made from
it with ``degrade_pings`` (``bayes_mpem.lbl.navigate.simulate``): the true step
between shots, less a random walk of ``q`` m/sqrt(s), rotated by a heading bias
and started 10 m (sd) off. The ship's transducer depth is trusted; ranges are
straight rays at one sound speed (SeaGap: the harmonic mean of ``ss_prof.inp``;
CC03: OBSrange's fitted 1506.86 m/s and 13 ms turn-around time; S05: the speed
``locate`` fits, with the deck box's TAT). Beacons: SeaGap's four transponders at ``pxp-ini.inp``;
CC03 at OBSrange's published solution (``CC03_obsrange_solution.txt``); S05 at
the location ``bayes_mpem.survey_in.location.locate`` finds (from the GPS track:
the transponder is taken as surveyed in). A surface ship has no separable
surface bounce, so ``navigate`` gives these beacons no multipath class; its
mixture is direct path against outliers.

SeaGap is also run on **ray-traced ranges**: the two-way travel times through
``ss_prof.inp`` (``navigate(..., travel_times="two-way", profile=...)``, the
equivalent straight-line ranges of ``bayes_mpem.lbl.navigate.ranges``), the
profile's sea surface 3 m above the mean transducer (SeaGap's ``XDUCER_DEPTH``,
as ``locate`` places it: the survey's heights are ellipsoidal). Beside
``navigate`` with and without the range scale, the baselines see the same
ranges: the Gaussian smoother (also with the range scale), the gate, and the
trilateration and EKF + RTS smoother of ``benchmarks/navigate_reference.py``
(the EKF at the sigma its own EM estimates).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import warnings
from pathlib import Path

import numpy as np

from bayes_mpem.acoustics.profile import SoundSpeedProfile
from bayes_mpem.io.formats import read_survey, sample_file
from bayes_mpem.io.geodesy import geodetic_to_enu
from bayes_mpem.lbl.navigate import navigate
from bayes_mpem.lbl.navigate.checks import model_checks, residual_summary
from bayes_mpem.lbl.navigate.simulate import degrade_pings
from bayes_mpem.survey_in.survey import SEAGAP_TRANSDUCER_DEPTH

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402
from navigate_reference import ekf_rts, trilaterate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CHI2_95 = 5.991


def seagap():
    raw = read_survey(sample_file("seagap/obsdata.inp"), "seagap")
    return raw.to_pings()


def seagap_times():
    """SeaGap's pings with the two-way travel times, and navigate's range-model options."""
    raw = read_survey(sample_file("seagap/obsdata.inp"), "seagap")
    pings, beacons = raw.to_pings()
    pings["range"] = pings["twtt"]
    prof = raw.header["ss_prof"]
    ray = {"travel_times": "two-way", "turnaround": 0.0,
           "profile": SoundSpeedProfile(prof["depth"].to_numpy(), prof["sound_speed"].to_numpy(),
                                        source="ss_prof.inp"),
           "surface_depth": float(pings["depth"].mean()) - SEAGAP_TRANSDUCER_DEPTH}
    return pings, beacons, ray


def cc03():
    raw = read_survey(sample_file("obsrange/SIO_CC03.txt"), "obsrange-sio")
    pings, beacons = raw.to_pings(sound_speed=1506.86, tat=0.013)
    e, n, _ = geodetic_to_enu(-4.88160, -132.68895, 0.0, raw.header["lat"], raw.header["lon"])
    beacons.loc[0, ["x", "y", "depth"]] = [float(e), float(n), 4739.13]
    return pings, beacons


def s05():
    from bayes_mpem.survey_in.location import locate

    raw = read_survey(sample_file("obsrange/WHOI_S05.txt"), "obsrange-whoi")
    pings, beacons = raw.to_pings()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = locate(pings, beacons, tat=raw.header["tat"])
    pings, beacons = raw.to_pings(sound_speed=res.sound_speed, tat=res.tat)
    beacons.loc[0, ["x", "y", "depth"]] = [res.east, res.north, res.depth]
    return pings, beacons


SURVEYS = {"SeaGap (4 transponders)": seagap, "OBSrange CC03 (1 beacon)": cc03,
           "OBSrange S05 (1 beacon)": s05}
METHODS = {"Gaussian smoother": {"model": "gaussian"}, "gate": {"model": "gate"},
           "this model": {}, "range scale": {"range_scale": True}}


def run(pings, beacons, *, heading_bias, q, seed, heading_sd=5.0):
    dr_pings, truth = degrade_pings(pings, heading_bias=heading_bias, dr_noise=q,
                                    start_error=10.0, rng=seed)
    xy = truth[["x", "y"]].to_numpy()
    out = {"dead reckoning": (_rmse(truth[["dr_x", "dr_y"]].to_numpy() - xy), np.nan, None)}
    for name, kw in METHODS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            nav = navigate(dr_pings, beacons, dr_noise=q, heading_sd=heading_sd, rng=0, **kw)
        err = nav.track - xy
        m2 = np.einsum("ka,ka->k", err, np.linalg.solve(nav.cov, err[..., None])[..., 0])
        out[name] = (_rmse(err), float(np.mean(m2 < CHI2_95)), nav)
    return out


RAY_METHODS = {"Gaussian smoother": {"model": "gaussian"},
               "Gaussian smoother + range scale": {"model": "gaussian", "range_scale": True},
               "gate": {"model": "gate"}, "this model": {},
               "this model + range scale": {"range_scale": True}}


def run_ray(pings, beacons, ray, *, heading_bias, q, seed, heading_sd=5.0):
    """Every method on SeaGap's ray-traced ranges: {method: (rmse, coverage, extra)}."""
    dr_pings, truth = degrade_pings(pings, heading_bias=heading_bias, dr_noise=q,
                                    start_error=10.0, rng=seed)
    xy = truth[["x", "y"]].to_numpy()
    out = {"dead reckoning": (_rmse(truth[["dr_x", "dr_y"]].to_numpy() - xy), np.nan, {})}
    for name, kw in RAY_METHODS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            nav = navigate(dr_pings, beacons, dr_noise=q, heading_sd=heading_sd, rng=0, **ray,
                           **kw)
        extra = {"sigma_dp": float(nav.state.sigma_dp), "k": float(nav.state.range_scale),
                 "flags": len(model_checks(nav)["flags"]), **residual_summary(nav)}
        out[name] = (*_score(nav.track, nav.cov, xy), extra)
    dive = nav.dive
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out["trilateration"] = (*_score(*trilaterate(dive), xy), {})
        tr, cov, sig = ekf_rts(dive, q=q, heading_sd=np.deg2rad(heading_sd))
    out["EKF + RTS (estimated sigma)"] = (*_score(tr, cov, xy), {"sigma_dp": float(sig)})
    return out


def _score(track, cov, xy):
    err = track - xy
    m2 = np.einsum("ka,ka->k", err, np.linalg.solve(cov, err[..., None])[..., 0])
    return _rmse(err), float(np.mean(m2 < CHI2_95))


def _rmse(err):
    return float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--ray-only", action="store_true")
    ap.add_argument("--why", action="store_true")
    args = ap.parse_args(argv)
    if args.why:
        return why(range(3))
    seeds = range(2 if args.quick else args.seeds)
    cases = [("heading bias 2 deg, q = 0.1 m/sqrt(s)", dict(heading_bias=2.0, q=0.1)),
             ("heading bias 0, q = 0.3 m/sqrt(s), heading prior sd 0.5 deg",
              dict(heading_bias=0.0, q=0.3, heading_sd=0.5))]
    rows = []
    for sname, load in ({} if args.ray_only else SURVEYS).items():
        pings, beacons = load()
        for cname, kw in cases:
            res = [run(pings, beacons, seed=s, **kw) for s in seeds]
            nav = res[0]["this model"][2]
            line = {m: (np.median([r[m][0] for r in res]), np.median([r[m][1] for r in res]))
                    for m in ("dead reckoning", *METHODS)}
            flagged = sum(not r["this model"][2].corrected for r in res)
            n_ol = int(np.sum(np.argmax(nav.resp, axis=1) == 2))
            rows.append((sname, cname, nav.dive.n, nav.dive.n_epochs, line, flagged, len(res),
                         n_ol))
            print(sname, cname, {k: round(v[0], 2) for k, v in line.items()}, flush=True)
    text = ["### Track error against the ship's GPS", "",
            f"`python benchmarks/navigate_measured.py` on {dt.date.today()} ({machine()}); "
            f"seeds 0 to {len(seeds) - 1} of the dead reckoning's errors, medians over them. "
            "RMSE: horizontal error of the track against the ship's GPS; coverage: epochs "
            "whose 95 % ellipse holds the GPS position; with the range scale: `navigate(..., "
            "range_scale=True)`, a sound-speed scale estimated with the track; outliers: "
            "replies this model labels "
            "outliers (seed 0); not corrected: runs with a `NavigationWarning` stretch.", "",
            "| survey | dead reckoning | ranges | epochs | DR RMSE (m) | Gaussian RMSE (m) | "
            "gate RMSE (m) | this model RMSE (m) | this model coverage | with the range scale: "
            "RMSE (m) | coverage | outliers | not corrected |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for sname, cname, n, k, line, flagged, runs, n_ol in rows:
        text.append(f"| {sname} | {cname} | {n:,} | {k:,} | {line['dead reckoning'][0]:.2f} | "
                    f"{line['Gaussian smoother'][0]:.2f} | {line['gate'][0]:.2f} | "
                    f"{line['this model'][0]:.2f} | {line['this model'][1]:.0%} | "
                    f"{line['range scale'][0]:.2f} | {line['range scale'][1]:.0%} | {n_ol} | "
                    f"{flagged}/{runs} |")
    text += ray_table(seeds, cases)
    print("\n".join(text))
    if not (args.quick or args.ray_only):
        write_section(ROOT / "docs" / "navigate.md", "navigate_measured", "\n".join(text))


def ray_table(seeds, cases):
    """The SeaGap ray-traced table: every method, both dead reckonings."""
    pings, beacons, ray = seagap_times()
    res = {cname: [run_ray(pings, beacons, ray, seed=s, **kw) for s in seeds]
           for cname, kw in cases}
    methods = list(next(iter(res.values()))[0])
    text = ["", "### SeaGap with ray-traced ranges", "",
            f"The same runs (seeds 0 to {len(seeds) - 1}) on the two-way travel times "
            "through `ss_prof.inp` (`navigate(..., travel_times=\"two-way\", profile=..., "
            "surface_depth=...)`); every method sees these ranges. Medians over the seeds; "
            "coverage also as min-max over the seeds; the trilateration's epochs without a "
            "fix have an infinite covariance (they count as covered).", "",
            "| method | " + " | ".join(f"{c}: RMSE (m) | coverage (min-max)" for c in res) + " |",
            "|---|" + "---:|---:|" * len(res)]
    for m in methods:
        cells = []
        for runs in res.values():
            r = [x[m][0] for x in runs]
            c = [x[m][1] for x in runs]
            cells.append(f"{np.median(r):.2f}")
            cells.append("-" if np.isnan(c[0]) else
                         f"{np.median(c):.1%} ({min(c):.1%}-{max(c):.1%})")
        text.append(f"| {m} | " + " | ".join(cells) + " |")
    text += ["", "What the ranges leave unmodelled (`navigate` with the range scale; medians):", "",
             "| dead reckoning | sigma_DP (m) | range scale | residual rms (m) | of it slow "
             "(10-min running mean, m) | lag-1 correlation | model-check flags |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for cname, runs in res.items():
        e = [x["this model + range scale"][2] for x in runs]
        med = {k: float(np.median([v[k] for v in e])) for k in e[0]}
        text.append(f"| {cname} | {med['sigma_dp']:.3f} | {med['k']:.6f} | {med['rms']:.3f} | "
                    f"{med['slow_rms']:.3f} | {med['lag1']:.2f} | {med['flags']:.0f} |")
    for cname, runs in res.items():
        print(cname, {m: round(float(np.median([x[m][0] for x in runs])), 3) for m in methods},
              flush=True)
    return text


def why(seeds):
    """Print how much of SeaGap's ray-traced misfit a sound speed changing in time explains.

    Diagnostic only (it uses the GPS): the ranges' relative error at the GPS positions,
    averaged over all transponders in a running window, is taken out of the ranges (an
    oracle sound-speed change in time), and navigate is rerun with the range scale. Then the
    same from the data alone (the window mean of navigate's own relative residuals, applied
    and navigate rerun, twice): a two-stage correction whose uncertainty is not propagated.
    """
    from bayes_mpem.lbl.navigate.objective import predictions
    from bayes_mpem.lbl.navigate.ranges import prepare

    pings, beacons, ray = seagap_times()
    conv, b, _ = prepare(pings, beacons, **ray)
    bx = beacons.set_index("beacon").loc[conv["beacon"], ["x", "y", "depth"]].to_numpy()
    dist = np.hypot(np.hypot(conv["x"] - bx[:, 0], conv["y"] - bx[:, 1]),
                    bx[:, 2] - conv["depth"]).to_numpy()
    rel, t = conv["range"].to_numpy() / dist - 1.0, conv["time"].to_numpy()

    def window_mean(v, tt, w):
        return np.array([v[np.abs(tt - x) <= w / 2].mean() for x in tt])

    def nav_score(p, seed):
        dr, truth = degrade_pings(p, heading_bias=2.0, dr_noise=0.1, start_error=10.0,
                                  rng=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            nav = navigate(dr, b, dr_noise=0.1, rng=0, range_scale=True)
        return nav, dr, (*_score(nav.track, nav.cov, truth[["x", "y"]].to_numpy()),
                         float(nav.state.sigma_dp))

    print("heading bias 2 deg, q = 0.1; medians over seeds", list(seeds),
          "of (RMSE m, coverage, sigma_DP m)")
    for w in (None, 600.0, 1800.0, 3600.0):
        slow = np.zeros_like(rel) if w is None else window_mean(rel, t, w)
        fixed = conv.copy()
        fixed["range"] = conv["range"] / (1.0 + slow)
        res = [nav_score(fixed, s)[2] for s in seeds]
        print("no correction" if w is None else f"oracle correction, {w:.0f} s window "
              f"(its sd {slow.std():.1e})", np.round(np.median(res, axis=0), 3), flush=True)
    res = []
    for s in seeds:
        cur = conv
        for _ in range(3):
            nav, _, score = nav_score(cur, s)
            d = nav.dive
            own = d.z / predictions(d, nav.state).direct - 1.0
            z = cur["range"].to_numpy().copy()
            z[d.rows] /= 1.0 + window_mean(own, d.times[d.epoch], 1800.0)
            cur = cur.copy()
            cur["range"] = z
        res.append(score)
    print("two-stage correction from the data (1800 s window, third pass)",
          np.round(np.median(res, axis=0), 3))


if __name__ == "__main__":
    main()
