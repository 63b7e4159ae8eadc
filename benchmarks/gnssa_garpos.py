"""`bayes-mpem locate` beside GARPOS on the same GNSS-A campaign files (issue 26).

GARPOS (Watanabe et al. 2020, doi:10.3389/feart.2020.597532; ``s-watanabe-jhod/garpos``,
GPL-3.0) is the field's reference implementation. It is not part of this project and is not
installed with it: this script runs a copy the user has built (its ``solveSingleEpoch.py``
and compiled ray tracer) as a separate program, on campaign files this project writes, and
compares the two array centres with each other and with the truth.

Run ``python benchmarks/gnssa_garpos.py GARPOS_BIN SOURCE SEEDS [--python PY]
[--lambda0 "0 1 2"] [--grad "-4 -3 -2"] [--mu-t "0"] [--locate OPTIONS] [--no-gradients]
[--jobs J]``:

* ``GARPOS_BIN``: the folder holding GARPOS's ``solveSingleEpoch.py`` and its
  ``garpos_v120/f90lib/lib_raytrace.so``;
* ``SOURCE``: ``sim`` (``bayes-mpem simulate --gnssa --format garpos --hours 6 --seed S``),
  ``indA`` / ``indB`` followed by ``-VARIANT`` parts (``indB``, ``indB-clean``,
  ``indB-clean-nograd``: the independently written generator of
  ``benchmarks/gnssa_independent.py``, its scenario and variants), or ``seagap`` (the shipped
  measured SeaGap survey rewritten as a GARPOS campaign, ``seagap_as_garpos``; SEEDS 1);
* ``SEEDS``: how many campaigns (seeds 0 to SEEDS - 1);
* ``--python``: the interpreter GARPOS runs under (numpy, scipy, pandas), this one by default;
* ``--lambda0`` / ``--grad``: GARPOS's grids of ``Log_Lambda0`` and ``Log_gradLambda`` (its
  ABIC chooses among them); its other settings are those of its sample ``Settings-prep.ini``
  (knots every 5 min, ``mu_t`` 0, ``mu_mt`` 0.5, 5-sigma rejection, 50 iterations);
* ``--mu-t``: GARPOS's grid of ``mu_t`` (minutes; with any above 0 its rejection is off,
  ``RejectCriteria`` 0, as GARPOS uses the correlation only then);
* ``--locate``: options for ``locate`` (``--gradients`` and ``--correlation`` only, e.g.
  ``"--correlation off"``);
* ``--no-gradients``: neither fits the gradient terms (GARPOS's ``knotint1`` and ``knotint2``
  0, ``locate --gradients off``; ``--grad`` is then ignored);
* ``--jobs``: how many GARPOS runs at once. ``locate`` runs beside them, so neither program's
  seconds are a speed measure.

``bayes-mpem locate SITE --out DIR`` runs with its defaults, and once more through
``locate_array_survey(raw, earth="flat")``: flat layers in the local frame, GARPOS's geometry.
Writes the section ``gnssa-garpos-SOURCE[-no-gradients][-mu-t][-LOCATE OPTIONS]`` of
``docs/gnssa.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
# the generator's module first: it holds BLAS to one thread before NumPy loads
import gnssa_independent as ind  # noqa: E402
import numpy as np  # noqa: E402
from gnssa_independent import AXES, DOC, locate  # noqa: E402
from scipy.stats import norm  # noqa: E402

Z95 = float(norm.ppf(0.975))

SETTINGS = """[HyperParameters]
ConstraintType0 = 2
ConstraintTypeGrad = 2
Log_Lambda0 = {lambda0}
Log_gradLambda = {grad}
mu_t = {mu_t}
mu_mt = 0.5

[Inv-parameter]
lib_directory = {lib}/
lib_raytrace = lib_raytrace.so
knotint0 = 5
knotint1 = {knots_grad}
knotint2 = {knots_grad}
RejectCriteria = {reject}
traveltimescale = 1.e-4
maxloop = 50
ConvCriteria = 5.e-3
deltap = 1.0e-6
deltab = 1.0e-6
"""


def write_source(source: str, seed: int, folder: Path) -> tuple[Path, np.ndarray]:
    """Write one campaign of ``source``; return its site file and the true array centre."""
    if source == "sim":
        from bayes_mpem.cli import main

        with contextlib.redirect_stdout(io.StringIO()):
            status = main(["simulate", "--gnssa", "--format", "garpos", "--hours", "6",
                           "--seed", str(seed), "--out", str(folder)])
        if status != 0:
            raise RuntimeError(f"bayes-mpem simulate --seed {seed}: exit status {status}")
        truth = json.loads((folder / "truth.json").read_text())["array_centre"]
        return next(folder.glob("*-initcfg.ini")), np.array([truth[a] for a in AXES])
    if source == "seagap":
        return seagap_as_garpos(folder), None
    scenario, *variants = source.removeprefix("ind").split("-")
    kw = {}
    for v in variants:
        kw.update(ind.VARIANTS[v])
    camp = ind.campaign(seed, replace(ind.Config(scenario=scenario), **kw))
    return ind.write_campaign(camp, folder), camp["truth"].mean(0)


def seagap_as_garpos(folder: Path) -> Path:
    """Write the shipped SeaGap survey (site G20) as a GARPOS campaign; return its site file.

    The shots are the transducer's positions that ``locate`` computes from SeaGap's antenna,
    attitude and lever arm, with no attitude and no lever arm left; SeaGap's frame, along the
    sphere, is turned into GARPOS's Cartesian one about its own origin (``array.from_sphere``),
    then lowered by the height of the profile's sea surface as ``locate`` takes it (3 m above the
    transducer's mean height), so that the frame's ``up = 0`` is the surface of ``svp.csv``.
    Times start at the first whole second.
    """
    import pandas as pd

    from bayes_mpem.io.formats import sample_file
    from bayes_mpem.io.garpos import write_garpos
    from bayes_mpem.io.geodesy import MEAN_EARTH_RADIUS_M
    from bayes_mpem.io.seagap import read_seagap
    from bayes_mpem.survey_in.array import from_sphere
    from bayes_mpem.survey_in.survey import seagap_surface_depth

    raw = read_seagap(sample_file("seagap/obsdata.inp"))
    site = next(line.split() for line in sample_file("seagap/site_info.txt").read_text()
                .splitlines() if line.startswith("G20"))
    pos, p = raw.transducer_positions(), raw.pings
    surface = -seagap_surface_depth(raw)  # its height, as locate takes it
    t0 = np.floor(p["t_tx"].min())
    names = {k: f"M{int(k):02d}" for k in raw.header["transponders"].index}
    shots = pd.DataFrame({"transponder": p["transponder"].map(names), "twtt": p["twtt"],
                          "t_tx": p["t_tx"] - t0, "t_rx": p["t_rx"] - t0})
    for end in ("tx", "rx"):
        e, n, u = from_sphere(*pos[end], MEAN_EARTH_RADIUS_M)
        shots[f"e_{end}"], shots[f"n_{end}"], shots[f"u_{end}"] = e, n, u - surface
        for a in ("head", "pitch", "roll"):
            shots[f"{a}_{end}"] = 0.0
    tp = raw.header["transponders"]
    e, n, u = from_sphere(tp["east"], tp["north"], tp["up"], MEAN_EARTH_RADIUS_M)
    u = u - surface
    prof = raw.header["ss_prof"]
    header = {"lat": float(site[2]), "lon": float(site[1]), "height": 0.0,
              "transponders": pd.DataFrame({"east": e, "north": n, "up": u},
                                           index=[names[k] for k in tp.index]),
              "atd_offset": [0.0, 0.0, 0.0],
              "ss_prof": {"depth": prof["depth"].to_numpy(),
                          "sound_speed": prof["sound_speed"].to_numpy()}}
    return write_garpos(folder, shots, header, site="G20", campaign="0000")


def garpos(bin_dir: Path, python: str, settings: Path, site: Path, out: Path,
           grid: tuple[list[float], ...]) -> dict:
    """Run GARPOS's ``solveSingleEpoch.py`` on ``site`` from its folder; read its solution.

    The solution is the model GARPOS chose (its ``-res.dat`` beside ``lambda/``), with
    ``grid``: every model of its grid (``lambda/``), each as :func:`read_result` gives it.
    """
    t0 = time.perf_counter()
    run = subprocess.run([python, str(bin_dir / "solveSingleEpoch.py"), "-i", str(settings),
                          "-f", site.name, "-d", str(out), "--maxcore", "1"],
                         cwd=site.parent, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    res = sorted(out.glob("*-res.dat"))
    if run.returncode != 0 or not res:
        raise RuntimeError(f"GARPOS on {site}: exit status {run.returncode}\n"
                           f"{run.stdout[-2000:]}{run.stderr[-2000:]}")
    sol = read_result(res[0], grid)
    sol["seconds"] = seconds
    sol["grid"] = [read_result(f, grid) for f in sorted((out / "lambda").glob("*-res.dat"))]
    return sol


def read_result(res: Path, grid: tuple[list[float], ...] = ([], [], [])) -> dict:
    """The array centre of a GARPOS ``-res.dat``, its covariance from ``-var.dat``, the model.

    Returns ``centre``, ``sd`` (m), ``model`` (log10 ``Lambda0``, log10 ``gradLambda``, ``mu_t``
    in minutes: from the file's name, ``_L+01.0_g-03.0_T5.0``, for what GARPOS searched, else the
    one value of ``grid``; None where neither gives it) and, where GARPOS's comment lines give
    them, ``abic`` and ``loops`` (the iterations it took).
    """
    text = res.read_text()

    def numbers(key):
        return [float(x) for x in re.search(rf"\n\s*{re.escape(key)}\s*=\s*(.*)", text)
                .group(1).split()]

    def comment(key):
        m = re.search(rf"#\s*{re.escape(key)}\s*=\s*([-+0-9.eE]+)", text)
        return float(m.group(1)) if m else None

    stations = re.search(r"\n\s*Stations\s*=\s*(.*)", text).group(1).split()
    rows = np.array([numbers(f"{s}_dPos")[:6] for s in stations])  # position, sigmas
    pos = rows[:, :3]
    cent = np.array(numbers("dCentPos")[:6])
    if np.any(cent[3:] != 0):
        raise RuntimeError(f"{res}: dCentPos was solved; this comparison fixes it (sigma 0)")
    cov = np.loadtxt(res.with_name(res.name.replace("-res.dat", "-var.dat")), delimiter=",")
    n = len(stations)
    avg = np.kron(np.ones((1, n)) / n, np.eye(3))
    model = []
    for key, values in zip(("L", "g", "T"), grid, strict=True):
        m = re.search(rf"_{key}([-+]?\d+(?:\.\d+)?)(?=[_-])", res.name)
        model.append(float(m.group(1)) if m else values[0] if len(values) == 1 else None)
    if np.any(rows[:, 3:] == 0):
        raise RuntimeError(f"{res}: a station coordinate was held (sigma 0); the covariance "
                           "read here assumes every station coordinate solved")
    loops = [int(m) for m in re.findall(r"#Inversion loop (\d+)", text)]
    return {"centre": pos.mean(0) + cent[:3],
            "sd": np.sqrt(np.diag(avg @ cov[:3 * n, :3 * n] @ avg.T)),
            "abic": comment("ABIC"), "model": None if None in model else tuple(model),
            "loops": max(loops, default=None)}


def ours(site: Path, out: Path, options=()) -> dict:
    """``bayes-mpem locate SITE --out OUT [OPTIONS]``, and again with flat layers."""
    from bayes_mpem.io.garpos import read_garpos
    from bayes_mpem.survey_in.array_survey import locate_array_survey

    def centre(summary):
        enu = summary["array_centre"]["enu"]
        return np.array([enu[a]["mean"] for a in AXES]), np.array([enu[a]["sd"] for a in AXES])

    summary, seconds = locate(site, out, options)
    c, sd = centre(summary)
    flat, _ = centre(locate_array_survey(read_garpos(site), earth="flat",
                                         **_keywords(options)).to_dict())
    return {"centre": c, "sd": sd, "flat": flat, "seconds": seconds}


def _keywords(options) -> dict:
    """``locate_array_survey``'s keywords for ``--gradients`` and ``--correlation`` options."""
    it = iter(options)
    kw = {o.removeprefix("--"): v for o, v in zip(it, it, strict=True)}
    if set(kw) - {"gradients", "correlation"}:
        raise SystemExit(f"--locate: only --gradients and --correlation, got {options}")
    if kw.get("correlation", "auto") not in ("auto", "off"):
        raise SystemExit("--locate: --correlation auto or off")
    return kw


def table(rows: list[dict], grid: tuple[list[float], ...]) -> list[tuple[str, str]]:
    """The comparison's measures over the campaigns, as (measure, value) pairs.

    Without a truth (a measured survey) only the two solutions' differences and sds.
    """
    truth = all(r["truth"] is not None for r in rows)
    ref = [r["truth"] if truth else np.zeros(3) for r in rows]
    g = np.array([r["garpos"]["centre"] - t for r, t in zip(rows, ref, strict=True)]) * 100
    o = np.array([r["ours"]["centre"] - t for r, t in zip(rows, ref, strict=True)]) * 100
    f = np.array([r["ours"]["flat"] - t for r, t in zip(rows, ref, strict=True)]) * 100
    sg = np.array([r["garpos"]["sd"] for r in rows]) * 100
    so = np.array([r["ours"]["sd"] for r in rows]) * 100

    def hv(e, how=np.median):
        return f"{how(np.hypot(e[:, 0], e[:, 1])):.2f} / {how(np.abs(e[:, 2])):.2f}"

    def three(v, fmt="{:.2f}"):
        return " / ".join(fmt.format(x) for x in v)

    chosen = [r["garpos"]["model"] for r in rows]
    edge = sum(c is not None and any(len(v) > 1 and np.isclose([min(v), max(v)], c[i]).any()
                                     for i, v in enumerate(grid)) for c in chosen)
    names = sorted({f"{c[0]:g}, {c[1]:g}, {c[2]:g}" for c in chosen if c is not None})
    spread = [max((np.hypot(*(m["centre"] - r["garpos"]["centre"])[:2]) for m in
                   r["garpos"]["grid"]), default=0.0) * 100 for r in rows]
    errors = [
        ("centre error, median horizontal / vertical (cm): GARPOS", hv(g)),
        ("the same: `locate` (defaults)", hv(o)),
        ("the same: `locate` with flat layers (`earth=\"flat\"`)", hv(f)),
    ]
    scores = [
        ("rms standardised error east / north / up: GARPOS",
         three(np.sqrt(np.mean((g / sg) ** 2, 0)))),
        ("the same: `locate`", three(np.sqrt(np.mean((o / so) ** 2, 0)))),
        ("centre's 95 % intervals covering (%): GARPOS / `locate`",
         f"{100 * np.mean(np.abs(g / sg) <= Z95):.0f} / "
         f"{100 * np.mean(np.abs(o / so) <= Z95):.0f}"),
    ]
    return [
        *(errors if truth else []),
        ("GARPOS minus `locate`, median (largest) horizontal / vertical (cm)",
         f"{hv(g - o)} ({hv(g - o, np.max)})"),
        ("GARPOS minus `locate` with flat layers, median horizontal / vertical (cm)",
         hv(g - f)),
        ("GARPOS minus `locate`, mean east / north / up (cm)", three((g - o).mean(0), "{:+.2f}")),
        ("centre sd, median east / north / up (cm): GARPOS", three(np.median(sg, 0))),
        ("the same: `locate`", three(np.median(so, 0))),
        *(scores if truth else []),
        ("GARPOS's choice of log10 Lambda0, log10 gradLambda, mu_t (min)",
         f"{'; '.join(names)} ({edge} of {len(rows)} at an edge of the grid)"),
        ("GARPOS's centre over its grid: the farthest model from the chosen, horizontally "
         "(cm; median, largest)", f"{np.median(spread):.2f}, {max(spread):.2f}"),
        ("GARPOS's chosen model at its 50-iteration limit",
         f"{sum((r['garpos']['loops'] or 0) >= 50 for r in rows)} of {len(rows)}"),
        ("seconds per campaign, median: GARPOS (all models of its grid) / `locate`",
         f"{np.median([r['garpos']['seconds'] for r in rows]):.0f} / "
         f"{np.median([r['ours']['seconds'] for r in rows]):.1f}"),
    ]


def main(argv=None) -> int:
    """Run the comparison and write its section of ``docs/gnssa.md``."""
    from _report import commit, machine, write_section

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("garpos_bin", type=Path)
    p.add_argument("source")
    p.add_argument("seeds", type=int)
    p.add_argument("--python", default=sys.executable)
    p.add_argument("--lambda0", default="0 1 2")
    p.add_argument("--grad", default="-4 -3 -2")
    p.add_argument("--jobs", type=int, default=1, help="GARPOS runs at once")
    p.add_argument("--mu-t", default="0", help="GARPOS's mu_t grid (minutes)")
    p.add_argument("--locate", default="", help="options for locate, in one string")
    p.add_argument("--no-gradients", action="store_true",
                   help="neither fits the gradients (GARPOS's knotint1 and knotint2 0)")
    args = p.parse_args(sys.argv[1:] if argv is None else argv)
    bin_dir = args.garpos_bin.resolve()
    lib = bin_dir / "garpos_v120" / "f90lib"
    if not (bin_dir / "solveSingleEpoch.py").is_file() or not (lib / "lib_raytrace.so").is_file():
        p.error(f"{bin_dir}: expected GARPOS's solveSingleEpoch.py and "
                "garpos_v120/f90lib/lib_raytrace.so there")
    scenario, *variants = args.source.removeprefix("ind").split("-")
    if args.source not in ("sim", "seagap") and not (
            args.source.startswith("ind") and scenario in ("A", "B")
            and set(variants) <= set(ind.VARIANTS)):
        p.error(f"SOURCE: expected sim, seagap, or indA / indB with -VARIANT parts of "
                f"{', '.join(ind.VARIANTS)}; got {args.source!r}")
    if args.source == "seagap" and args.seeds != 1:
        p.error("seagap: one survey, SEEDS 1")
    if args.no_gradients:  # GARPOS's gradLambda then weighs nothing: one model per value
        args.grad = "0"
    grid = tuple([float(x) for x in v.split()] for v in (args.lambda0, args.grad, args.mu_t))
    t_all = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        settings = tmp / "settings.ini"
        correlated = any(float(m) > 0 for m in args.mu_t.split())
        settings.write_text(SETTINGS.format(lambda0=args.lambda0, grad=args.grad, lib=lib,
                                            knots_grad=0 if args.no_gradients else 5,
                                            mu_t=args.mu_t, reject=0 if correlated else 5.0))
        options = (["--gradients", "off"] if args.no_gradients else []) + args.locate.split()
        camps = [write_source(args.source, seed, tmp / f"c{seed}") for seed in range(args.seeds)]
        pool = ThreadPoolExecutor(args.jobs)  # each GARPOS is its own process
        runs = [pool.submit(garpos, bin_dir, args.python, settings, site, tmp / f"g{seed}", grid)
                for seed, (site, _) in enumerate(camps)]
        try:
            for seed, ((site, truth), run) in enumerate(zip(camps, runs, strict=True)):
                row = {"truth": truth, "ours": ours(site, tmp / f"o{seed}", options),
                       "garpos": run.result()}
                rows.append(row)
                ref = np.zeros(3) if truth is None else truth  # a measured survey: as solved
                cm = {k: np.round((row[k]["centre"] - ref) * 100, 2) for k in ("garpos", "ours")}
                print(seed, "GARPOS", cm["garpos"], row["garpos"]["model"], "ours", cm["ours"],
                      "flat", np.round((row["ours"]["flat"] - ref) * 100, 2), flush=True)
        finally:  # a failure stops the runs still queued
            pool.shutdown(cancel_futures=True)
    cmd = (f"python benchmarks/gnssa_garpos.py GARPOS_BIN {args.source} {args.seeds} "
           f"--lambda0 \"{args.lambda0}\""
           + ("" if args.no_gradients else f" --grad \"{args.grad}\"") + f" --jobs {args.jobs}"
           + (" --no-gradients" if args.no_gradients else "")
           + (f" --mu-t \"{args.mu_t}\"" if args.mu_t != "0" else "")
           + (f" --locate \"{args.locate}\"" if args.locate else ""))
    lines = [f"Written by `{cmd}` ({machine()}; {time.perf_counter() - t_all:.0f} s; "
             f"git {commit()}).", "",
             (f"{args.seeds} campaigns (seeds 0-{args.seeds - 1}) of `{args.source}`; the "
              "centre minus the truth" if args.source != "seagap" else
              "The shipped SeaGap survey (site G20, measured; no truth) as a GARPOS campaign")
             + "; GARPOS v1.2.0 as built by the user, ABIC over its grid"
             + ("; neither fits the gradients." if args.no_gradients else "."), "",
             "| measure | value |", "|---|---|"]
    lines += [f"| {m} | {v} |" for m, v in table(rows, grid)]
    text = "\n".join(lines)
    print(text)
    tags = [args.source, "no-gradients" * args.no_gradients, "mu-t" * correlated,
            "-".join(o.strip("-") for o in args.locate.split())]
    write_section(DOC, "gnssa-garpos-" + "-".join(t for t in tags if t), text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
