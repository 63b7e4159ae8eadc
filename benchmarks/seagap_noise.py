"""The real SeaGap survey: are its replies' residuals correlated, and what does modelling it do?

The shipped SeaGap survey (site G20, four transponders at 2.7 km, 3,347 replies over 14.6 h) is
located with independent replies (``correlation="off"``) and with the default
(``"auto"``: GARPOS's data covariance where the marginal likelihood prefers it), the gradient
terms as the argument asks (``locate --gradients``; default ``off``, as docs/gnssa.md's numbers
were measured; ``auto`` fits them on this track). Printed:

* the correlation of the independent fit's residuals (true replies) between pairs of replies
  by time apart, for one transponder and between transponders;
* both fits' array centres, their sds and the noise chosen;
* a check on real data without a truth: the survey cut into 2 and 4 blocks of equal shots,
  each located on its own, and the scatter of the blocks' centres against their reported sds
  (``chi2 / dof`` about their weighted mean; 1 where the sds are honest, with few degrees of
  freedom).

Run (about a minute; several with the gradients)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/seagap_noise.py [auto|on|off]
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

import numpy as np

from bayes_mpem.io.formats import read_survey, sample_file
from bayes_mpem.survey_in.array_survey import locate_array_survey

LAGS = ((0, 0), (0, 60), (60, 120), (120, 300), (300, 600), (600, 1200), (1200, 3600))


def residual_correlation(fit, time):
    """Rows ``(lo, hi, rho same transponder, rho other transponders)`` of the true replies."""
    keep = fit.p_true > 0.5
    t, r, k = time[keep], fit.residual[keep], fit.index[keep]
    r = r - r.mean()
    out = []
    for lo, hi in LAGS:
        dt = t[None, :] - t[:, None]
        pair = (dt == 0) & np.triu(np.ones_like(dt, bool), 1) if hi == 0 else (dt > lo) & (dt <= hi)
        same = k[:, None] == k[None, :]
        rho = [float(np.sum((r[:, None] * r[None, :])[pair & m]) / max((pair & m).sum(), 1)
                     / np.mean(r * r)) for m in (same, ~same)]
        out.append((lo, hi, *rho))
    return out


def blocks(raw, n, correlation, gradients):
    """``chi2 / dof`` per axis of ``n`` blocks' centres about their weighted mean, and the sds.

    With ``gradients="auto"`` each block is gated on its own track, so the blocks' models may
    differ.
    """
    t = raw.pings["time"].to_numpy(float)
    edges = np.quantile(t, np.linspace(0, 1, n + 1))
    edges[-1] += 1.0
    ms, sds = [], []
    for b in range(n):
        sel = (t >= edges[b]) & (t < edges[b + 1])
        part = dataclasses.replace(raw, pings=raw.pings[sel].reset_index(drop=True))
        m, C = locate_array_survey(part, correlation=correlation,
                                   gradients=gradients).fits["array"].centre()
        ms.append(m)
        sds.append(np.sqrt(np.diag(C)))
    ms, sds = np.array(ms), np.array(sds)
    mean = np.average(ms, axis=0, weights=1 / sds**2)
    return np.sum(((ms - mean) / sds) ** 2, axis=0) / (n - 1), sds


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("gradients", nargs="?", default="off", choices=("auto", "on", "off"),
                   help="locate --gradients (default off, as docs/gnssa.md's first numbers)")
    gradients = p.parse_args().gradients
    warnings.simplefilter("ignore")
    print(f"gradients={gradients!r}")
    raw = read_survey(sample_file("seagap/obsdata.inp"))
    time = raw.pings["time"].to_numpy(float)
    fits = {c: locate_array_survey(raw, correlation=c, gradients=gradients)
            for c in ("off", "auto")}
    fit = fits["off"].fits["array"]
    print("residual correlation of the independent fit (true replies) by time apart:")
    for lo, hi, same, other in residual_correlation(fit, time[fit.rows]):
        span = "same interrogation" if hi == 0 else f"{lo}-{hi} s"
        print(f"  {span:>18}: one transponder {same:+.3f}, between transponders {other:+.3f}")
    for c, res in fits.items():
        m, C = res.fits["array"].centre()
        nz = res.summary["noise"]
        print(f"{c}: centre {np.round(m, 4)} m, sd {np.round(1e3 * np.sqrt(np.diag(C)), 1)} mm;"
              f" noise mu_t {nz['correlation_s']:g} s, mu_mt {nz['share']}, white {nz['white']}")
    for n in (2, 4):
        for c in ("off", "auto"):
            chi, sds = blocks(raw, n, c, gradients)
            print(f"{n} blocks, {c}: chi2/dof east/north/up {np.round(chi, 2)}; block sds (mm) "
                  f"{np.round(1e3 * sds, 0).tolist()}")


if __name__ == "__main__":
    main()
