"""Do the array's intervals cover the truth? 20 simulated GNSS-A surveys, GARPOS and GNATSS files.

Each survey (:func:`bayes_mpem.survey_in.gnssa_simulate.simulate_gnssa`, seeds 0-19):
4 transponders at about 1,500 m, 4 hours of shots every 20 s along transits
across the array, an antenna-transducer offset turned by the attitude, a
sound-speed profile scaled by a factor that changes in time (0.5 m/s), timing
noise 50 microseconds, 2 cm GNSS noise, 5 % spurious replies, 2 % missing. It is
written as GARPOS files and as GNATSS files, read back, and located by
``locate_array_survey`` (the survey's profile, 16 speed intervals of 15 min).

Reported per format: how often each coordinate's 95 % interval and each
transponder's 95 % region (the ellipsoid of its covariance) contain the truth,
the spread of the standardised errors, the array centre's coverage, the shots
classified as the simulation made them, and seconds per survey. Also the same
surveys with the model-based (not cluster-robust) covariance, to show what the
robust one is for.

Writes the section ``gnssa-coverage`` of ``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_coverage.py [N_SURVEYS]
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2, norm

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

from bayes_mpem.io.garpos import read_garpos, write_garpos  # noqa: E402
from bayes_mpem.io.gnatss import read_gnatss, write_gnatss  # noqa: E402
from bayes_mpem.survey_in.array_survey import locate_array_survey  # noqa: E402
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

CI = 0.95
INTERVALS = 16
SETTINGS = {"n_transponders": 4, "depth": 1500.0, "hours": 4.0, "shot_interval": 20.0,
            "sigma": 5e-5, "p_spurious": 0.05, "p_missing": 0.02, "speed_amplitude": 0.5}


def one_survey(seed, folder):
    """Locate one simulated survey from both formats; per-transponder rows of results."""
    sim = simulate_gnssa(rng=seed, origin=(38.0, 143.0, 20.0), **SETTINGS)
    raws = {"garpos": lambda: read_garpos(write_garpos(folder / "g", sim.pings, sim.header)),
            "gnatss": lambda: read_gnatss(write_gnatss(folder / "n", sim.pings, sim.header,
                                                       transducer_delay=0.13))}
    truth = sim.truth["transponders"]
    rows = []
    for fmt, read in raws.items():
        t0 = time.perf_counter()
        res = locate_array_survey(read(), speed_intervals=INTERVALS, ci=CI)
        seconds = time.perf_counter() - t0
        fit = res.fits["array"]
        called = np.zeros(len(sim.pings), bool)
        called[fit.rows] = fit.p_true < 0.5
        spurious = sim.truth["spurious"]
        if fmt == "gnatss":  # the reader's shot order: by interrogation, then transponder
            order = np.lexsort((sim.pings["transponder"], sim.pings["t_tx"]))
            spurious = spurious[order]
        m, C = fit.centre()
        cz = (m - truth.loc[list(fit.ids)].to_numpy().mean(axis=0)) / np.sqrt(np.diag(C))
        G = np.kron(np.ones(len(fit.ids)) / len(fit.ids), np.eye(3))
        cz_model = (m - truth.loc[list(fit.ids)].to_numpy().mean(axis=0)) / np.sqrt(
            np.diag(G @ fit.cov_model[:G.shape[1], :G.shape[1]] @ G.T))
        for k, tid in enumerate(fit.ids):
            err = fit.enu[k] - truth.loc[tid].to_numpy()
            cov = fit.position_cov(k)
            cov_m = fit.cov_model[3 * k:3 * k + 3, 3 * k:3 * k + 3]
            rows.append({"format": fmt, "seed": seed, "transponder": tid, "err": err,
                         "z": err / np.sqrt(np.diag(cov)),
                         "d2": float(err @ np.linalg.solve(cov, err)),
                         "z_model": err / np.sqrt(np.diag(cov_m)),
                         "d2_model": float(err @ np.linalg.solve(cov_m, err)),
                         "centre_z_model": cz_model,
                         "centre_z": cz, "match": float(np.mean(called == spurious)),
                         "missed": int(np.sum(spurious & ~called)),
                         "false": int(np.sum(~spurious & called)), "seconds": seconds,
                         # the profile's mean scale: fitted against the simulated one
                         "speed_err": (fit.sound_speed / fit.model["unit"]
                                       - float(np.mean(sim.truth["scale"]))),
                         "speed_sd": fit.sound_speed_sd / fit.model["unit"]})
    return rows


def table(rows, label, suffix=""):
    """Markdown rows of the coverage numbers, per format (``suffix``: "" or "_model")."""
    q = norm.ppf(0.5 + CI / 2)
    lines = []
    for fmt in ("garpos", "gnatss"):
        r = [x for x in rows if x["format"] == fmt]
        z = np.array([x["z" + suffix] for x in r])
        d2 = np.array([x["d2" + suffix] for x in r])
        cz = np.array([x["centre_z" + suffix] for x in r[::4]])
        cov_c = np.mean(np.abs(z) < q, axis=0)
        err_mm = 1e3 * np.array([x["err"] for x in r])
        lines.append(
            f"| {fmt} | {label} | {len(r) // 4} | {100 * np.mean(np.abs(z) < q):.1f} | "
            + " / ".join(f"{100 * v:.0f}" for v in cov_c)
            + f" | {100 * np.mean(d2 <= chi2.ppf(CI, 3)):.1f} | "
            + " / ".join(f"{v:.2f}" for v in z.std(axis=0))
            + f" | {100 * np.mean(np.abs(cz) < q):.0f} | "
            + " / ".join(f"{v:.1f}" for v in np.sqrt(np.mean(err_mm**2, axis=0)))
            + f" | {100 * np.mean([x['match'] for x in r[::4]]):.2f} | "
            f"{sum(x['missed'] for x in r[::4])} / {sum(x['false'] for x in r[::4])} | "
            f"{np.mean([x['seconds'] for x in r[::4]]):.1f} |")
    return lines


def main(n_surveys=20):
    rows, t0 = [], time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(n_surveys):
            rows += one_survey(seed, Path(tmp) / str(seed))
            print(f"survey {seed} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    load = os.getloadavg()
    head = ("| format | intervals | surveys | coordinates covered (%) | east / north / up (%) "
            "| transponder regions covered (%) | sd of z, east / north / up | array centre "
            "covered (%, 3 coords) | rms error (mm), east / north / up | shots classified as "
            "simulated (%) | spurious missed / true called spurious | s per survey |\n"
            "|---|---|---:|---:|---|---:|---|---:|---|---:|---|---:|")
    text = (f"Written by `python benchmarks/gnssa_coverage.py {n_surveys}` ({machine()}; "
            f"{time.perf_counter() - t0:.0f} s, load average {load[0]:.1f} / {load[1]:.1f} / "
            f"{load[2]:.1f}: the seconds need a re-run on a quiet machine; git "
            f"{commit()}).\n\n"
            f"{n_surveys} surveys x 4 transponders per format; {100 * CI:g} % intervals "
            "(Wald, cluster-robust by interrogation) and regions (the covariance's ellipsoid, "
            f"squared radius {chi2.ppf(CI, 3):.2f}).\n\n"
            + head + "\n" + "\n".join(table(rows, "cluster-robust")
                                        + table(rows, "model-based", "_model")) + "\n")
    speed = np.array([x["speed_err"] / x["speed_sd"] for x in rows[::4]])
    text += (f"\nThe profile's mean scale over the survey (the sound speed's time average), "
             f"standardised error: mean {speed.mean():+.2f}, sd {speed.std():.2f} over "
             f"{speed.size} fits.\n")
    write_section(ROOT / "docs" / "gnssa.md", "gnssa-coverage", text)
    print(text)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
