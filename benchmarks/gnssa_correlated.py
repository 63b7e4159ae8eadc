"""Noise correlated in time: the array's intervals with and without GARPOS's data covariance.

The acceptance's campaigns (``simulate_gnssa(hours=6, speed_model="field",
track="star+circle", gradients=True, rng=seed)``: four transponders at 1,500 m, 50 us of
white timing noise, 2 cm GNSS noise, 5 % spurious replies), with a delay added to every
reply that the simulator does not make and that is not GARPOS's covariance either: for
each transponder its own Ornstein-Uhlenbeck process (``PER_SD`` us, ``PER_TAU`` s: water
along that transponder's rays) plus one shared by all (``COMMON_SD`` us, ``COMMON_TAU``
s). The sizes follow the SeaGap survey's residuals (a transponder's replies a minute
apart correlated at 0.57, at 5-10 minutes at 0.19; ``docs/gnssa.md``). Each campaign is
located with ``correlation="off"`` (independent replies, the intervals cluster-robust by
interrogation), with the default ``"auto"`` (GARPOS's covariance where the marginal
likelihood prefers it, the true replies refitted by generalised least squares), and with
the covariance given near the truth (``(180, 0, 0.6)``: what the choice could reach).

Reported per setting: the centre's and the transponders' errors, the coverage of their
95 % intervals, the rms of the standardised errors, and the correlation time chosen.
Writes the section ``gnssa-correlated`` of ``docs/gnssa.md`` and prints it::

    python benchmarks/gnssa_correlated.py [N_SEEDS]

``--sample``: the posterior instead (``sample_array`` of the ``off`` and the ``auto`` fits,
seed = the campaign's; the EM's columns beside them), section
``gnssa-correlated-posterior``.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import commit, machine, write_section  # noqa: E402
from gnssa_independent import ou_path  # noqa: E402  (the same process, written once)

from bayes_mpem.survey_in.array_sampling import AXES, sample_array  # noqa: E402
from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey  # noqa: E402
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa  # noqa: E402

DOC = Path(__file__).resolve().parents[1] / "docs" / "gnssa.md"
PER_SD, PER_TAU = 40e-6, 180.0
COMMON_SD, COMMON_TAU = 20e-6, 600.0
#: ``correlation`` of each fit: independent, the default, and near the truth (the
#: per-transponder process's time, no share, the white share of the variance about 0.6:
#: 50 us timing and the GNSS noise against 40 us per transponder)
SETTINGS = {"off": "off", "auto": "auto", "given": (PER_TAU, 0.0, 0.6)}


def campaign(seed):
    """The simulated campaign with the correlated delays added; its raw survey and truth."""
    sim = simulate_gnssa(hours=6, speed_model="field", track="star+circle", gradients=True,
                         rng=seed)
    raw = sim.raw()
    rng = np.random.default_rng(10_000 + seed)
    p = raw.pings
    t = p["time"].to_numpy(float)
    order = np.argsort(t, kind="stable")
    delay = np.zeros(t.size)
    delay[order] = ou_path(rng, t[order], COMMON_SD, COMMON_TAU)
    for k in p["transponder"].unique():
        sel = np.flatnonzero(p["transponder"].to_numpy() == k)
        sel = sel[np.argsort(t[sel], kind="stable")]
        delay[sel] += ou_path(rng, t[sel], PER_SD, PER_TAU)
    p = p.copy()
    p["twtt"] = p["twtt"].to_numpy(float) + delay
    raw = dataclasses.replace(raw, pings=p)
    truth = sim.truth["transponders"][["east", "north", "up"]].to_numpy()
    return raw, truth


def _record(m, sd, enu, tsd, truth, noise, seconds):
    return {"err": m - truth.mean(0), "sd": sd, "tp_err": enu - truth, "tp_sd": tsd,
            "tau": noise["correlation_s"], "share": noise.get("share"),
            "white": noise.get("white"), "seconds": seconds}


def run(n_seeds, sample=False):
    """Return ``{setting: [per-seed record]}`` (``"<setting>, posterior"`` with ``sample``)."""
    settings = ("off", "auto") if sample else tuple(SETTINGS)
    rows = {}
    for seed in range(n_seeds):
        raw, truth = campaign(seed)
        for s in settings:
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fit = locate_array_survey(raw, correlation=SETTINGS[s]).fits["array"]
            m, C = fit.centre()
            tsd = np.sqrt(np.diag(fit.cov)[:3 * len(fit.ids)]).reshape(-1, 3)
            noise = fit.model["noise"] or {"correlation_s": 0.0}
            rec = _record(m, np.sqrt(np.diag(C)), fit.enu, tsd, truth, noise,
                          time.perf_counter() - t0)
            rows.setdefault(s, []).append(rec)
            print(seed, s, np.round(100 * rec["err"], 2), np.round(rec["err"] / rec["sd"], 2),
                  noise["correlation_s"], flush=True)
            if not sample:
                continue
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                post = sample_array(array_shots(raw), fit, rng=seed, progress=False)
            c = post.centre()
            pos = [post.position(tid) for tid in post.ids]
            rec = _record(np.array([c[a]["mean"] for a in AXES]),
                          np.array([c[a]["sd"] for a in AXES]),
                          np.array([[q[a]["mean"] for a in AXES] for q in pos]),
                          np.array([[q[a]["sd"] for a in AXES] for q in pos]), truth, noise,
                          time.perf_counter() - t0)
            rec["converged"] = post.converged
            rec["move"] = ("independence move" if post.diagnostics.get("moves", "").startswith(
                "MHMove") else "differential evolution")
            rows.setdefault(f"{s}, posterior", []).append(rec)
            print(seed, s, "posterior", np.round(100 * rec["err"], 2),
                  np.round(rec["err"] / rec["sd"], 2), post.converged, flush=True)
    return rows


def report(rows, n_seeds, seconds):
    """The Markdown section."""
    def col(recs):
        e = np.array([r["err"] for r in recs])
        s = np.array([r["sd"] for r in recs])
        z = e / s
        te = np.array([r["tp_err"] for r in recs])
        ts = np.array([r["tp_sd"] for r in recs])
        tz = te / ts
        picks = [f"{r['tau']:g} s" + ("" if not r["tau"] else
                                      f" / {r['share']:g} / {r['white']:g}") for r in recs]
        vals, counts = np.unique(picks, return_counts=True)
        return [
            f"{100 * np.median(np.hypot(e[:, 0], e[:, 1])):.2f} / "
            f"{100 * np.median(np.abs(e[:, 2])):.2f}",
            " / ".join(f"{100 * v:.2f}" for v in np.median(s, axis=0)),
            f"{100 * np.mean(np.abs(z) < 1.96):.0f} (" + " / ".join(
                f"{100 * v:.0f}" for v in np.mean(np.abs(z) < 1.96, axis=0)) + ")",
            " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean(z**2, axis=0))),
            f"{100 * np.mean(np.abs(tz) < 1.96):.0f} (" + " / ".join(
                f"{100 * v:.0f}" for v in np.mean(np.abs(tz) < 1.96, axis=(0, 1))) + ")",
            " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean(tz**2, axis=(0, 1)))),
            ", ".join(f"{v}: {c}" for v, c in zip(vals, counts, strict=True)),
            f"{np.median([r['seconds'] for r in recs]):.1f}"]

    names = ["centre error, median horizontal / vertical (cm)",
             "centre sd, median east / north / up (cm)",
             "centre's 95 % intervals covering (%; east / north / up)",
             "rms standardised error of the centre, east / north / up",
             "transponders' 95 % intervals covering (%; east / north / up)",
             "rms standardised error of the transponders, east / north / up",
             "mu_t / mu_mt / white used (campaigns)", "seconds per fit (median)"]
    sample = any(", posterior" in s for s in rows)
    if sample:
        names[-1] = "seconds per fit or per sampling (median)"
        names.append("posteriors converged; the move that sampled them")
    cols = {s: col(rows[s]) + ([f"{sum(r['converged'] for r in rows[s])} of {len(rows[s])}; "
                                + ", ".join(f"{m} {n}" for m, n in zip(*np.unique(
                                    [r["move"] for r in rows[s]], return_counts=True),
                                    strict=True))]
                               if sample and "converged" in rows[s][0] else
                               ["-"] * sample) for s in rows}
    heads = {"off": "off", "auto": "auto (default)", "given": "given",
             "off, posterior": "off, posterior", "auto, posterior": "auto, posterior (default)"}
    order = [s for s in heads if s in rows]
    what = ("located with `correlation=\"off\"` and with the default `\"auto\"`, each then "
            "sampled (`sample_array`, its defaults; coverage from the posterior mean and sd)"
            if sample else
            "located with `correlation=\"off\"`, with the default `\"auto\"`, and with the "
            "covariance given near the truth (`(180, 0, 0.6)`)")
    lines = [f"Written by `python benchmarks/gnssa_correlated.py {n_seeds}"
             f"{' --sample' if sample else ''}` ({machine()}; {seconds:.0f} s; git {commit()}).",
             "",
             f"{n_seeds} campaigns of 6 h (`star+circle`, the sound-speed field, gradients), "
             f"plus per transponder an Ornstein-Uhlenbeck delay of {1e6 * PER_SD:g} us and "
             f"{PER_TAU:g} s and a common one of {1e6 * COMMON_SD:g} us and "
             f"{COMMON_TAU:g} s; {what}.",
             "", "| measure | " + " | ".join(heads[s] for s in order) + " |",
             "|---|" + "---|" * len(order)]
    lines += [f"| {n} | " + " | ".join(cols[s][i] for s in order) + " |"
              for i, n in enumerate(names)]
    return "\n".join(lines)


def main(argv=None) -> int:
    """Run the study and write its section of ``docs/gnssa.md``."""
    argv = sys.argv[1:] if argv is None else argv
    sample = "--sample" in argv
    argv = [a for a in argv if a != "--sample"]
    n_seeds = int(argv[0]) if argv else 20
    t0 = time.perf_counter()
    rows = run(n_seeds, sample)
    text = report(rows, n_seeds, time.perf_counter() - t0)
    print(text)
    write_section(DOC, "gnssa-correlated-posterior" if sample else "gnssa-correlated", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
