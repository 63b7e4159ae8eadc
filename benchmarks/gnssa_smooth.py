"""The smooth sound speed of the array fit: accuracy, coverage and knot-spacing stability.

Each campaign (:func:`bayes_mpem.survey_in.gnssa_simulate.simulate_gnssa`, seeds
0 to N-1): four transponders at about 1 500 m, ``hours`` hours (default 6) of shots every
20 s along the ``star+circle`` track, the sound-speed *field* (three sinusoids of 12.42, 6
and 2 hours, 1, 0.7 and 0.5 m/s at the surface, decaying over 400 m) with the horizontal
gradients switched off, timing noise 50 us, 2 cm GNSS noise, 5 % spurious replies. It is
located by ``locate_array_survey`` with its defaults (a smooth spline, knots every 5 min,
its weight by maximum marginal likelihood), then with knots every 2.5 and 10 min.

Reported: the array centre's error (median horizontal and vertical), the coverage of
the centre's 95 % intervals (3 coordinates per campaign), how often halving or doubling
the knot spacing moves each centre coordinate by less than its reported sd, and the
seconds per fit (default knots; the first fit of the process is left out of the timing
because it warms up the ray tracer).

``SIM_GRADIENTS`` 1 simulates the horizontal gradients (0.5 and 0.1 (m/s)/km at the surface
and through the column, turning once in 12 h); ``FIT_GRADIENTS`` is ``locate``'s
``--gradients``: ``auto`` (the default: fitted where the track constrains them, as on these
campaigns), ``on`` (or 1) or ``off`` (or 0); where fitted, how often their time averages are
within 2 sd of the truth's is reported, and how much of the truth's series lies in the 95 %
bands of ``summary.json``'s series (as for the sound speed's: its series against the fit's
reference plus the true change of the depth-averaged speed). ``SCENARIO``: ``default``;
``staggered`` (the transponders interrogated in turn); ``clean`` (no spurious replies).

Writes the section ``gnssa-accept-SIM-FIT-SCENARIO`` of ``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_smooth.py [N_SEEDS] [HOURS] [SIM_GRADIENTS] [FIT_GRADIENTS] [SCENARIO]
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402

from bayes_mpem.survey_in.array_survey import locate_array_survey  # noqa: E402
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa, true_speed_change  # noqa: E402

SPACINGS = (5.0, 2.5, 10.0)
#: times in ``summary.json``'s series (``array_survey``'s 121)
SERIES_TIMES = 121


def _centre(res):
    fit = res.fits["array"]
    m, C = fit.centre()
    return m, np.sqrt(np.diag(C)), fit


GRAD_TRUTH = {"shallow_east": "grad1_east", "shallow_north": "grad1_north",
              "deep_east": "grad2_east", "deep_north": "grad2_north"}


def _band_cover(summary, truth):
    """Share of the series' times whose truth lies in the 95 % band: speed, then each gradient.

    The speed against the fit's reference plus the true change of the depth-averaged speed
    (about the points the fit's gradient terms are about);
    a gradient against the truth's series (zero without gradients); None where not fitted.
    """
    ss = summary["sound_speed"]["series"]
    t = np.asarray(ss["time_s"], float)
    true_v = summary["sound_speed"]["reference_m_s"] + true_speed_change(
        truth, t, summary["gradients"].get("origins_m"))
    out = [np.mean(np.abs(np.asarray(ss["mean_m_s"]) - true_v)
                   < 1.959964 * np.asarray(ss["sd_m_s"]))]
    gs, tg = summary["gradients"].get("series"), truth["gradients"]
    for name, key in GRAD_TRUTH.items():
        if gs is None:
            out.append(np.nan)
            continue
        true_g = np.interp(t, tg["time_s"], tg[key]) if tg else np.zeros(t.size)
        out.append(np.mean(np.abs(np.asarray(gs[name]["mean"]) - true_g)
                           < 1.959964 * np.asarray(gs[name]["sd"])))
    return np.array(out)


SCENARIOS = {"default": {}, "staggered": {"schedule": "staggered"},
             "three-deep": {"n_transponders": 3, "depth": 5000.0},
             "clean": {"p_spurious": 0.0}}


def run(n_seeds, hours, sim_grad=False, fit_grad="auto", scenario="default"):
    """Return the per-seed records."""
    locate_array_survey(simulate_gnssa(hours=0.5, rng=999, speed_model="field").raw())  # warm
    rows = []
    for seed in range(n_seeds):
        sim = simulate_gnssa(hours=hours, rng=seed, speed_model="field", track="star+circle",
                             gradients=sim_grad, **SCENARIOS[scenario])
        raw = sim.raw()
        true_tp = sim.truth["transponders"][["east", "north", "up"]].to_numpy()
        truth = true_tp.mean(axis=0)
        record = sim.truth_record()
        rec = record["gradients"]
        out = {}
        for km in SPACINGS:
            t0 = time.perf_counter()
            res = locate_array_survey(raw, knot_minutes=km, gradients=fit_grad)
            m, sd, fit = _centre(res)
            out[km] = (m, sd, time.perf_counter() - t0, fit, res.summary["gradients"])
            if km == 5.0:
                out_summary = res.summary
        m, sd, secs, fit, gsum = out[5.0]
        err = m - truth
        moves = np.array([np.abs(out[km][0] - m) < sd for km in (2.5, 10.0)])
        sm = fit.model["smoothing"]
        grad_z = None
        if gsum["fitted"]:
            g = fit.model["gradients"]
            grad_z = np.array([(g[k]["mean"] - (np.mean(rec[v]) if rec else 0.0)) / g[k]["sd"]
                               for k, v in GRAD_TRUTH.items()])
        tp_z = (fit.enu - true_tp) / fit.sd
        rows.append({"seed": seed, "err": err, "sd": sd, "z": err / sd, "moves_ok": moves,
                     "tp_err": np.abs(fit.enu - true_tp).max(), "grad_z": grad_z,
                     "tp_z": tp_z, "fitted": gsum["fitted"],
                     "moves": np.array([out[km][0] - m for km in (2.5, 10.0)]),
                     "seconds": secs, "n_shots": int(fit.index.size),
                     "bands": _band_cover(out_summary, record),
                     "log10_weight": sm["log10_weight"], "edf": sm["effective_dof"]})
        print(f"seed {seed}: err cm {np.round(100 * err, 2)}, sd cm {np.round(100 * sd, 2)}, "
              f"moves cm 2.5 {np.round(100 * rows[-1]['moves'][0], 2)} 10 "
              f"{np.round(100 * rows[-1]['moves'][1], 2)}, {secs:.2f} s, "
              f"log10 weight {sm['log10_weight']:.2f}, edf {sm['effective_dof']:.1f}",
              flush=True)
    return rows


def report(rows, n_seeds, hours, seconds, sim_grad=False, fit_grad="auto", scenario="default"):
    """Return the Markdown section."""
    err = np.array([r["err"] for r in rows])
    tp_cover = np.concatenate([np.abs(r["tp_z"]) < 1.959964 for r in rows])  # (seeds K, 3)
    fitted = [r for r in rows if r["grad_z"] is not None]
    z = np.array([r["z"] for r in rows])
    sd = np.array([r["sd"] for r in rows])
    ok = np.array([r["moves_ok"] for r in rows])  # (seeds, 2, 3)
    horiz = np.hypot(err[:, 0], err[:, 1])
    cover = np.abs(z) < 1.959964
    git = commit()
    secs = np.array([r["seconds"] for r in rows])
    shots = np.array([r["n_shots"] for r in rows])
    return "\n".join([
        f"Written by `python benchmarks/gnssa_smooth.py {n_seeds} {hours:g} {int(sim_grad)} "
        f"{fit_grad} {scenario}` ({machine()}; {seconds:.0f} s; git {git}).",
        "",
        f"{n_seeds} campaigns of {hours:g} h (`star+circle`, the sound-speed field, "
        f"{'with' if sim_grad else 'no'} gradients, {scenario}; {int(np.median(shots))} "
        "replies each, median), located with the defaults (smooth spline, knots every 5 min, "
        f"gradients={fit_grad}: fitted in {len(fitted)} of {len(rows)}), then with knots "
        "every 2.5 and 10 min.",
        "",
        "| measure | value | goal |",
        "|---|---|---|",
        f"| centre error, median horizontal / vertical (cm) | {100 * np.median(horiz):.2f} / "
        f"{100 * np.median(np.abs(err[:, 2])):.2f} | 1 / 2 |",
        f"| centre error, largest horizontal / vertical (cm) | {100 * horiz.max():.2f} / "
        f"{100 * np.abs(err[:, 2]).max():.2f} | |",
        "| centre sd, median east / north / up (cm) | "
        + " / ".join(f"{100 * v:.2f}" for v in np.median(sd, axis=0)) + " | |",
        f"| 95 % intervals of the centre covering the truth (% of {cover.size}) | "
        f"{100 * cover.mean():.1f} (east / north / up "
        + " / ".join(f"{100 * v:.0f}" for v in cover.mean(axis=0)) + ") | 90-98 |",
        "| rms of the standardised errors, east / north / up | "
        + " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean(z**2, axis=0))) + " | 1 |",
        "| centre error, mean east / north / up (cm) | "
        + " / ".join(f"{100 * v:+.2f}" for v in err.mean(axis=0)) + " | 0 |",
        f"| 95 % intervals of the transponders' coordinates covering the truth (% of "
        f"{tp_cover.size}) | {100 * tp_cover.mean():.1f} (east / north / up "
        + " / ".join(f"{100 * v:.0f}" for v in tp_cover.mean(axis=0)) + ") | 90-98 |",
        f"| knots 2.5 or 10 min: centre coordinate moved by less than its sd (% of "
        f"{ok.size}) | {100 * ok.mean():.1f} | >= 95 |",
        "| largest move, 2.5 / 10 min (in sds) | "
        + " / ".join(f"{np.max(np.abs(np.array([r['moves'][j] for r in rows])) / sd):.2f}"
                     for j in range(2)) + " | |",
        f"| seconds per fit, median (largest) | {np.median(secs):.2f} ({secs.max():.2f}) | "
        "<= 5 for 3 000 shots |",
        f"| log10 smoothing weight, median (range) | "
        f"{np.median([r['log10_weight'] for r in rows]):.2f} "
        f"({min(r['log10_weight'] for r in rows):.2f} to "
        f"{max(r['log10_weight'] for r in rows):.2f}) | |",
        f"| effective degrees of freedom of the fit, median | "
        f"{np.median([r['edf'] for r in rows]):.1f} | |",
        f"| largest transponder error, median (largest) (cm) | "
        f"{100 * np.median([r['tp_err'] for r in rows]):.2f} "
        f"({100 * max(r['tp_err'] for r in rows):.2f}) | 3 |",
        f"| campaigns with every transponder within 3 cm (%) | "
        f"{100 * np.mean([r['tp_err'] < 0.03 for r in rows]):.0f} | 100 |"]
        + [f"| seeds {b}-{b + 19}: centre error, median horizontal / vertical (cm); centre "
           f"covered (%) | {100 * np.median(horiz[b:b + 20]):.2f} / "
           f"{100 * np.median(np.abs(err[b:b + 20, 2])):.2f}; "
           f"{100 * cover[b:b + 20].mean():.0f} (up {100 * cover[b:b + 20, 2].mean():.0f}) "
           "| 1 / 2; 90-98 |" for b in range(0, len(rows) - 19 if len(rows) > 20 else 0, 20)]
        + [f"| 95 % band of the sound speed against time covering the true change (% of "
           f"{len(rows) * SERIES_TIMES} times) | "
           f"{100 * np.mean([r['bands'][0] for r in rows]):.1f} | 90-98 |"]
        + ([] if not fitted else [
            f"| time-averaged gradients within 2 sd of the truth, shallow E / N, deep E / N "
            f"(% of {len(fitted)} fitted) | " + " / ".join(
                f"{100 * v:.0f}" for v in np.mean([np.abs(r['grad_z']) < 2 for r in fitted],
                                                  axis=0))
            + " | >= 90 without gradients |",
            f"| 95 % bands of the gradients against time covering the truth, shallow E / N, "
            f"deep E / N (% of {len(fitted) * SERIES_TIMES} times each) | " + " / ".join(
                f"{100 * v:.1f}" for v in np.mean([r['bands'][1:] for r in fitted], axis=0))
            + " | 90-98 |"]))


def main(argv=None):
    """Run the benchmark and write its section."""
    argv = sys.argv[1:] if argv is None else argv
    n_seeds = int(argv[0]) if argv else 20
    hours = float(argv[1]) if len(argv) > 1 else 6.0
    sim_grad = len(argv) > 2 and argv[2] == "1"
    fit_grad = {"1": "on", "0": "off"}.get(argv[3], argv[3]) if len(argv) > 3 else "auto"
    scenario = argv[4] if len(argv) > 4 else "default"
    t0 = time.perf_counter()
    rows = run(n_seeds, hours, sim_grad, fit_grad, scenario)
    text = report(rows, n_seeds, hours, time.perf_counter() - t0, sim_grad, fit_grad, scenario)
    print(text)
    name = f"gnssa-accept-{int(sim_grad)}-{fit_grad}-{scenario}"
    write_section(ROOT / "docs" / "gnssa.md", name, text)


if __name__ == "__main__":
    main()
