"""Held-out gain of each model extension on the measured surveys in ``data/``.

For every transponder of the OBSrange samples and of the SeaGap example, the
simulation's assumptions (straight rays, one sound speed, spurious pings uniform
over the window; a flat local frame) are the baseline, and each extension is
scored against it by 5-fold cross-validated log predictive density per ping
(:func:`bayes_mpem.survey_in.heldout.heldout_logpdf`; paired differences summed over the
pings, with their standard error), with random folds and with folds that are
contiguous blocks of time. Also: residual rms, pings that change class, and how
far the transponder estimate moves.

Writes the section ``measured-gain`` of ``docs/measured-data.md`` and prints it::

    python benchmarks/measured_gain.py
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, write_section  # noqa: E402

from bayes_mpem.exceptions import LocateWarning  # noqa: E402
from bayes_mpem.io.formats import read_survey  # noqa: E402
from bayes_mpem.survey_in.heldout import heldout_logpdf  # noqa: E402
from bayes_mpem.survey_in.location import locate  # noqa: E402
from bayes_mpem.survey_in.survey import SEAGAP_TRANSDUCER_DEPTH, survey_profile  # noqa: E402

DATA = ROOT / "data"
SURVEYS = [  # file, format, profile (the survey's own cast where there is one, else the atlas)
    ("obsrange/SIO_CC03.txt", "obsrange-sio", DATA / "obsrange" / "CC03_ssp.txt"),
    ("obsrange/SIO_EC03.txt", "obsrange-sio", "woa09"),
    ("obsrange/SIO_WC03.txt", "obsrange-sio", "woa09"),
    ("obsrange/WHOI_S05.txt", "obsrange-whoi", "woa09"),
    ("seagap/obsdata.inp", "seagap", "survey"),
]


def intervals_for(pings) -> int:
    """The time-varying speed's B-spline: one interval per hour of survey (at least 1)."""
    hours = (pings["time"].max() - pings["time"].min()) / 3600.0
    return max(1, int(round(hours)))


def models(raw, pings, prof):
    """The extensions, as keyword sets for :func:`locate`."""
    geo = {}
    if raw.format == "seagap":
        geo = {"earth_radius": 6371000.0,
               "surface_depth": float(pings["depth"].mean()) - SEAGAP_TRANSDUCER_DEPTH}
    k = intervals_for(pings)
    out = {"baseline (simulation's assumptions)": {},
           "first-arrival outliers": {"outliers": "first_arrival"},
           "position lag along the track": {"fit_lag": True}}
    if geo:
        out["sphere + sea-surface datum"] = dict(geo)
    out[f"refraction ({prof.source.split('(')[0].strip() or 'profile'})"] = dict(geo, ssp=prof)
    out[f"speed varying in time ({k} interval{'s' if k > 1 else ''})"] = dict(
        geo, speed_intervals=k)
    out["refraction + speed varying in time"] = dict(geo, ssp=prof, speed_intervals=k)
    return out


def gain(a, b):
    d = b - a
    return float(d.sum()), float(np.sqrt(d.size) * d.std(ddof=1))


def main():
    rows, refr_rows = [], []
    t_start = time.time()
    for name, fmt, ssp in SURVEYS:
        raw = read_survey(DATA / name, fmt)
        pings, beacons = raw.to_pings()
        tat = raw.header.get("tat", 0.0 if fmt == "seagap" else None)
        prof = survey_profile(raw, ssp)
        for tid in beacons["beacon"].astype(str):
            fits, cv, cvb = {}, {}, {}
            for label, kw in models(raw, pings, prof).items():
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", LocateWarning)
                    fits[label] = locate(pings, beacons, tid, tat=tat, **kw)
                    cv[label] = heldout_logpdf(pings, beacons, tid, tat=tat, rng=0, **kw)
                    cvb[label] = heldout_logpdf(pings, beacons, tid, tat=tat, folds="blocked",
                                                **kw)
            base = next(iter(fits))
            b = fits[base]
            for label, f in fits.items():
                g, se = gain(cv[base], cv[label])
                gb, seb = gain(cvb[base], cvb[label])
                moved = int(np.sum((f.p_true < 0.5) != (b.p_true < 0.5)))
                dh = float(np.hypot(f.east - b.east, f.north - b.north))
                rows.append(f"| {Path(name).stem} {tid} | {label} | {g:+.1f} ± {se:.1f} | "
                            f"{gb:+.1f} ± {seb:.1f} | {1e3 * f.sigma:.3f} | {f.n_spurious} | "
                            f"{moved} | {dh:.2f} | {f.depth - b.depth:+.2f} | "
                            f"{f.sound_speed:.2f} |")
            # refraction's own gain once the time variation is modelled
            labels = list(fits)
            g, se = gain(cv[labels[-2]], cv[labels[-1]])
            gb, seb = gain(cvb[labels[-2]], cvb[labels[-1]])
            g0, se0 = gain(cv[base if fmt != "seagap" else labels[2]], cv[labels[-3]])
            refr_rows.append(f"| {Path(name).stem} {tid} | {g0:+.1f} ± {se0:.1f} | "
                             f"{g:+.1f} ± {se:.1f} | {gb:+.1f} ± {seb:.1f} | "
                             f"{1e3 * fits[labels[-2]].sigma:.3f} -> "
                             f"{1e3 * fits[labels[-1]].sigma:.3f} |")
            print(f"{name} {tid} done ({time.time() - t_start:.0f} s)", flush=True)
    text = "\n".join([
        "Written by `python benchmarks/measured_gain.py` "
        f"({machine()}; {time.time() - t_start:.0f} s).",
        "",
        "Held-out gain over the baseline: 5-fold cross-validated log predictive density, "
        "summed over the transponder's pings (nats, ± standard error of the paired sum); "
        "'random' folds, and 'blocked' folds that are contiguous in time. Then the residual "
        "scatter of the true arrivals (`sigma`), pings called spurious, pings whose class "
        "changed from the baseline's, and how far the estimate moved (horizontal, depth) "
        "from it.",
        "",
        "| survey, transponder | model | gain, random folds | gain, blocked folds | sigma (ms) "
        "| spurious | class changes | moved (m) | depth change (m) | sound speed (m/s) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|",
        *rows,
        "",
        "Refraction's own gain: without the time variation (refraction against the straight "
        "rays, same geometry), and with it (refraction + speed varying in time against the speed "
        "varying in time alone):",
        "",
        "| survey, transponder | without time variation | with it, random folds | "
        "with it, blocked folds | sigma (ms) |",
        "|---|---:|---:|---:|---:|",
        *refr_rows,
    ])
    write_section(ROOT / "docs" / "measured-data.md", "measured-gain", text)
    print(text)


if __name__ == "__main__":
    main()
