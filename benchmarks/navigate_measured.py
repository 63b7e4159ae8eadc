"""Navigation on measured surveys: real ranges, a GPS truth, a dead reckoning made from it.

Run from the repository root::

    python benchmarks/navigate_measured.py           # writes its section of docs/navigate.md
    python benchmarks/navigate_measured.py --quick   # 2 seeds, prints only

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
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import warnings
from pathlib import Path

import numpy as np

from bayes_mpem.io.formats import read_survey, sample_file
from bayes_mpem.io.geodesy import geodetic_to_enu
from bayes_mpem.lbl.navigate import navigate
from bayes_mpem.lbl.navigate.simulate import degrade_pings

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CHI2_95 = 5.991


def seagap():
    raw = read_survey(sample_file("seagap/obsdata.inp"), "seagap")
    return raw.to_pings()


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


def _rmse(err):
    return float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args(argv)
    seeds = range(2 if args.quick else args.seeds)
    cases = [("heading bias 2 deg, q = 0.1 m/sqrt(s)", dict(heading_bias=2.0, q=0.1)),
             ("heading bias 0, q = 0.3 m/sqrt(s), heading prior sd 0.5 deg",
              dict(heading_bias=0.0, q=0.3, heading_sd=0.5))]
    rows = []
    for sname, load in SURVEYS.items():
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
    print("\n".join(text))
    if not args.quick:
        write_section(ROOT / "docs" / "navigate.md", "navigate_measured", "\n".join(text))


if __name__ == "__main__":
    main()
