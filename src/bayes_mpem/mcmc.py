"""Mcmc (moved from ``bayes``)."""

from __future__ import annotations

import sys

import emcee
import numpy as np

from .lbl.posterior import BeaconPosterior


def _default_moves():
    # Differential evolution proposals (ter Braak & Vrugt 2008) with a snooker
    # update: on this near-Gaussian, correlated 5-D posterior they gave shorter
    # autocorrelation times than the default stretch move (docs/bayes.md).
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


def _progress_bar(progress, desc):
    if progress == "auto":
        progress = sys.stderr.isatty()
    if not progress:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dependency
        return None
    return tqdm(desc=desc, unit="step", leave=False)


def _bulk_ess_min(chain):
    """Smallest ArviZ bulk ESS over the columns of a ``(steps, walkers, ndim)`` chain."""
    import arviz_stats as azs

    arr = np.transpose(chain, (1, 0, 2))  # (walker = chain, step = draw, ndim)
    return float(np.min(azs.ess(arr, method="bulk", chain_axis=0, draw_axis=1)))


def run_ensemble(post: BeaconPosterior, start, *, seed, moves=None, tau_factor=50.0,
                 min_ess=1000.0, max_steps=20000, check_every=250, progress="auto"):
    """Run one emcee ensemble until it is long enough by three measures.

    The kept chain must be ``tau_factor`` autocorrelation times long, and its
    smallest ESS must reach ``min_ess`` both by emcee's ``steps x walkers / tau``
    and by ArviZ's rank-normalised bulk ESS (walkers as chains).

    Parameters
    ----------
    post : BeaconPosterior
    start : numpy.ndarray
        ``(n_walkers, ndim)`` initial positions.
    seed : int
        Seeds emcee's random state.
    moves : list, optional
        emcee moves (default: 80 % DEMove, 20 % DESnookerMove).
    tau_factor : float, default 50
    min_ess : float, default 1000
        Per ensemble; 0 to stop on ``tau_factor`` alone.
    max_steps : int, default 20000
    check_every : int, default 250
    progress : bool or "auto"

    Returns
    -------
    sampler : emcee.EnsembleSampler
    burn : int
        Steps discarded as burn-in: ``ceil(2 max tau)``.
    tau : numpy.ndarray
        Autocorrelation time of each parameter on the kept chain.
    converged : bool
    status : str
        How far the run got against each stopping test (for the warning).
    """
    n_walkers, ndim = start.shape
    sampler = emcee.EnsembleSampler(n_walkers, ndim, post, vectorize=True,
                                    moves=moves or _default_moves())
    sampler.random_state = np.random.RandomState(seed % 2**32).get_state()
    bar = _progress_bar(progress, f"beacon {post.beacon} ({post.priors} priors)")
    state, burn, tau, converged = start, 0, np.full(ndim, np.inf), False
    ess_bulk = 0.0
    try:
        while sampler.iteration < max_steps:
            state = sampler.run_mcmc(state, min(check_every, max_steps - sampler.iteration),
                                     progress=False)
            tau_all = sampler.get_autocorr_time(tol=0, quiet=True)
            burn = int(np.ceil(2.0 * np.max(tau_all)))
            kept = sampler.iteration - burn
            if kept > 0:
                tau = sampler.get_autocorr_time(discard=burn, tol=0, quiet=True)
            if bar is not None:
                bar.update(check_every)
                bar.set_postfix(tau=f"{np.max(tau):.0f}",
                                ess=f"{kept * n_walkers / np.max(tau):.0f}")
            long_enough = (kept > 0 and np.all(np.isfinite(tau))
                           and kept >= tau_factor * np.max(tau)
                           and kept * n_walkers / np.max(tau) >= min_ess)
            if long_enough:
                ess_bulk = (_bulk_ess_min(sampler.get_chain(discard=burn)) if min_ess > 0
                            else np.inf)
                if ess_bulk >= min_ess:
                    converged = True
                    break
    finally:
        if bar is not None:
            bar.close()
    kept = sampler.iteration - burn
    status = (f"{sampler.iteration} steps, burn-in {burn}, kept {kept} = "
              f"{kept / np.max(tau):.1f} tau (needs {tau_factor:g}), emcee ESS "
              f"{max(kept, 0) * n_walkers / np.max(tau):.0f} and bulk ESS "
              f"{ess_bulk:.0f} (need {min_ess:g})")
    return sampler, burn, tau, converged, status
