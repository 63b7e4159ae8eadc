"""Simulation-based calibration of a beacon's posterior and sampler (docs/bayes-calibration.md)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ..._rng import RNGLike, as_generator
from ...io.survey import BeaconData
from ...mcmc.sbc import rank_statistic, rank_uniformity
from ..em.em_mixture import fit_mixture_em
from ..model.beacon_geometry import BeaconGeometry
from .beacon_chains import beacon_chains, sampled
from .posterior import BeaconPosterior

#: The prior of the calibration: plane depth within this many m of the sea surface ...
PLANE_HALFWIDTH = 30.0
#: ... scales log-uniform on these bounds (m) ...
SIGMA_BOUNDS = (1.0, 20.0)
#: ... and the listening window from 1 m to this many times the longest possible
#: multipath, plus 200 m.
WINDOW_FACTOR = 1.25


@dataclass(frozen=True)
class SBCResult:
    """Ranks of the true parameters among their posterior draws, over the simulations.

    Attributes
    ----------
    names : tuple of str
        The natural parameters ranked (:data:`~bayes_mpem.lbl.bayes.posterior.PARAMS`).
    ranks : numpy.ndarray
        ``(n_sims, len(names))`` ranks, each in ``0 .. n_draws``.
    truths : numpy.ndarray
        ``(n_sims, len(names))`` the values drawn from the prior.
    n_draws : int
        Posterior draws each rank is taken among.
    settings : dict
        The design, the prior and the sampler's options.
    diagnostics : dict
        Per simulation: steps run, the smallest ESS, whether the stopping rule was met.
    """

    names: tuple
    ranks: np.ndarray = field(repr=False)
    truths: np.ndarray = field(repr=False)
    n_draws: int
    settings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict, repr=False)

    def tests(self, *, n_bins: int = 10, tails: float = 0.1) -> dict:
        """Test every parameter's ranks for uniformity (:func:`.rank_uniformity`).

        Returns
        -------
        dict
            Parameter name to the test's dict.
        """
        return {k: rank_uniformity(self.ranks[:, i], self.n_draws, n_bins=n_bins, tails=tails)
                for i, k in enumerate(self.names)}


def sbc_design(data: BeaconData, *, min_direct: float = 200.0) -> BeaconData:
    """Keep the pings of ``data`` whose direct path is at least ``min_direct`` m long.

    Parameters
    ----------
    data : BeaconData
        A beacon's replies; only the vehicle positions and the beacon position are used.
    min_direct : float, default 200
        Shortest direct path kept (m): ten times the largest scale of the prior,
        so no simulated range falls below the window's start.
    """
    geom = BeaconGeometry.from_data(data)
    keep = geom.direct >= float(min_direct)
    return replace(data, range=data.range[keep], x=data.x[keep], y=data.y[keep],
                   depth=data.depth[keep], time=data.time[keep], rows=data.rows[keep])


def sbc_posterior(design: BeaconData, *, path: str = "triangle",
                  plane_halfwidth: float = PLANE_HALFWIDTH, sigma_bounds=SIGMA_BOUNDS,
                  concentration: float = 1.0, priors: str = "learned") -> BeaconPosterior:
    """Build the calibration's posterior for ``design``: a prior that ignores the ranges.

    ``d0`` within ``plane_halfwidth`` of the sea surface, the scales log-uniform on
    ``sigma_bounds``, the outliers uniform over a window that holds every simulated range.

    Returns
    -------
    BeaconPosterior
        On the design's own ranges (replace them before use: :func:`simulate_ranges`).
    """
    geom = BeaconGeometry.from_data(design)
    depth = float(design.position[2])
    d0_hi = depth + float(plane_halfwidth)
    top = float(np.max(geom.multipath(d0_hi, path)))
    window = (min(1.0, geom.lo), max(WINDOW_FACTOR * top + 200.0, geom.hi))
    return BeaconPosterior(design, priors=priors, path=path, concentration=concentration,
                           sigma_bounds=tuple(sigma_bounds),
                           d0_bounds=(depth - float(plane_halfwidth), d0_hi), window=window)


def simulate_ranges(post: BeaconPosterior, theta, gen) -> np.ndarray:
    """Draw one range per ping of ``post``'s design from the model at ``theta``.

    Parameters
    ----------
    post : BeaconPosterior
        Gives the geometry, the path and the outliers' window.
    theta : numpy.ndarray
        ``(ndim,)`` parameters in the sampler's coordinates.

    Returns
    -------
    numpy.ndarray
        ``(n,)``.

    Raises
    ------
    ValueError
        When a range falls outside the window (a design with too short direct paths).
    """
    p = {k: float(v[0, 0]) for k, v in post.unpack(np.atleast_2d(theta)).items()}
    g = post.geom
    cls = gen.choice(3, size=g.n, p=[p["w_dp"], p["w_mp"], p["w_ol"]])
    dp = g.direct + p["sigma_dp"] * gen.standard_normal(g.n)
    mp = g.multipath(p["d0"], post.path) + p["sigma_mp"] * gen.standard_normal(g.n)
    ol = gen.uniform(g.lo, g.hi, g.n)
    z = np.choose(cls, [dp, mp, ol])
    if np.any((z < g.lo) | (z > g.hi)):
        raise ValueError(f"a simulated range left the window [{g.lo:g}, {g.hi:g}] m: keep "
                         "only pings with longer direct paths (sbc_design)")
    return z


def run_sbc(design: BeaconData, n_sims: int, *, rng: RNGLike = None, sampler="auto",
            n_draws: int = 99, path: str = "triangle", n_walkers=None,
            min_ess: float = 300.0, max_steps: int = 20000, **prior) -> SBCResult:
    """Simulation-based calibration of the beacon posterior on ``design``.

    Parameters
    ----------
    design : BeaconData
        The vehicle positions (:func:`sbc_design`).
    n_sims : int
        Simulations (prior draw, data, posterior).
    rng : None, int or numpy.random.Generator
        The only source of randomness.
    sampler : {"auto", "independence", "ensemble"}
        As for :func:`~bayes_mpem.lbl.bayes.beacon_sampling.sample_beacon`.
    n_draws : int, default 99
        Posterior draws each rank is taken among, thinned evenly from the kept chain.
    n_walkers : int, optional
        Walkers (:func:`~bayes_mpem.lbl.bayes.beacon_chains.beacon_chains`).
    min_ess, max_steps : float, int
        The sampler's stopping rule.
    **prior
        ``plane_halfwidth``, ``sigma_bounds``, ``concentration``, ``priors``
        (:func:`sbc_posterior`).
    """
    gen = as_generator(rng)
    base = sbc_posterior(design, path=path, **prior)
    opts = {"path": path, "priors": base.priors, "concentration": base.concentration,
            "sigma_bounds": tuple(np.exp(base.log_sigma_bounds)), "d0_bounds": base.d0_bounds,
            "window": (base.geom.lo, base.geom.hi)}
    names = sampled(base)
    ranks = np.empty((int(n_sims), len(names)), int)
    truths = np.empty((int(n_sims), len(names)))
    diag = {"n_steps": [], "sampler": [], "converged": []}
    for s in range(int(n_sims)):
        theta = base.draw_prior(1, gen)[0]
        data = replace(design, range=simulate_ranges(base, theta, gen))
        post = BeaconPosterior(data, **opts)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # flagged fits and step caps are counted instead
            post.em = fit_mixture_em(data, path=path, rng=gen)
            run = beacon_chains(post, gen, sampler=sampler, n_walkers=n_walkers,
                                min_ess=min_ess, max_steps=max_steps, n_draws=n_draws,
                                progress=False)
        chain = run.chain
        per_chain = -(-n_draws // chain.shape[1])
        idx = np.linspace(0, chain.shape[0] - 1, per_chain).round().astype(int)
        flat = chain[idx].reshape(-1, post.ndim)
        flat = flat[np.linspace(0, flat.shape[0] - 1, n_draws).round().astype(int)]
        draws = post.unpack(flat)
        truth = post.unpack(theta[None, :])
        for i, k in enumerate(names):
            truths[s, i] = truth[k][0, 0]
            ranks[s, i] = rank_statistic(draws[k][:, 0], truth[k][0, 0])
        diag["n_steps"].append(run.run.n_steps)
        diag["sampler"].append(run.sampler)
        diag["converged"].append(run.run.converged)
    settings = {"n_sims": int(n_sims), "n_ranges": int(design.n), "path": path,
                "sampler": sampler, "n_walkers": n_walkers, "min_ess": float(min_ess),
                **{k: (list(v) if isinstance(v, tuple) else v) for k, v in opts.items()}}
    return SBCResult(names=tuple(names), ranks=ranks, truths=truths, n_draws=int(n_draws),
                     settings=settings, diagnostics=diag)
