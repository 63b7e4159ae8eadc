"""Equal against learned mixing priors: PSIS-LOO, interval shifts, class changes (docs/bayes.md).

References
----------
Vehtari, A., Gelman, A. and Gabry, J. (2017). Practical Bayesian model evaluation using
leave-one-out cross-validation and WAIC. *Statistics and Computing* 27, 1413-1432.
Sivula, T., Magnusson, M. and Vehtari, A. (2020). Uncertainty in Bayesian leave-one-out
cross-validation based model comparison. arXiv:2008.10296.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..._rng import RNGLike, as_generator
from ...io.survey import BeaconData
from .beacon_sampling import PosteriorResult, sample_beacon

CLEAR = 2.0  # standard errors
MIN_DIFF = 4.0  # nats: smaller differences are practically nil


@dataclass(frozen=True)
class LooResult:
    """PSIS-LOO of one posterior.

    Attributes
    ----------
    elpd, se : float
        Expected log pointwise predictive density and its standard error.
    elpd_i, pareto_k : numpy.ndarray
        Per range; ``pareto_k`` is NaN for ranges with a tied tail (plain IS).
    good_k : float
        ArviZ's k-hat threshold for this number of draws.
    n_constant : int
        Ranges with a tied tail, handled by plain importance sampling.
    """

    elpd: float
    se: float
    elpd_i: np.ndarray = field(repr=False)
    pareto_k: np.ndarray = field(repr=False)
    good_k: float
    n_constant: int


def psis_loo(result: PosteriorResult) -> LooResult:
    """PSIS-LOO with ArviZ; ranges whose Pareto tail is tied handled by plain IS-LOO.

    Why the tied tails: ``docs/bayes.md`` (Equal against learned priors).

    Raises
    ------
    ValueError
        When ``result`` holds no ``log_likelihood`` group.
    """
    import arviz_stats as azs
    from scipy.special import logsumexp

    if "log_likelihood" not in result.idata.children:
        raise ValueError(f"beacon {result.beacon}: PSIS-LOO needs the per-range "
                         "log-likelihood: sample with log_likelihood=True")
    vals = result.idata.log_likelihood["z"].values  # (chain, draw, range)
    ratios = -vals.reshape(-1, vals.shape[-1])  # log importance ratios, (draws, ranges)
    n_draws = ratios.shape[0]
    top = np.partition(ratios, n_draws - 5, axis=0)[n_draws - 5:]
    tied = (top.max(axis=0) - top.min(axis=0)) < np.finfo(float).tiny
    elpd_i = np.empty(vals.shape[-1])
    k = np.full(vals.shape[-1], np.nan)
    elpd_i[tied] = np.log(n_draws) - logsumexp(ratios[:, tied], axis=0)
    good_k = 0.7
    if (~tied).any():
        sub = result.idata.isel(range=np.flatnonzero(~tied))
        with warnings.catch_warnings():
            # ArviZ warns for k-hat above its threshold; the counts are reported instead
            warnings.simplefilter("ignore", UserWarning)
            loo = azs.loo(sub, pointwise=True, var_name="z")
        elpd_i[~tied] = np.asarray(loo.elpd_i)
        k[~tied] = np.asarray(loo.pareto_k)
        good_k = float(loo.good_k) if loo.good_k is not None else 0.7
    n = elpd_i.size
    return LooResult(elpd=float(elpd_i.sum()), se=float(np.sqrt(n * np.var(elpd_i))),
                     elpd_i=elpd_i, pareto_k=k, good_k=good_k, n_constant=int(tied.sum()))


@dataclass(frozen=True)
class PriorComparison:
    """Equal against learned priors for one beacon.

    Attributes
    ----------
    beacon : str
    equal, learned : PosteriorResult
    elpd : dict
        ``{"equal": (elpd, se), "learned": (elpd, se)}`` from PSIS-LOO.
    elpd_diff, elpd_diff_se : float
        Learned minus equal, and its paired standard error.
    pareto_k : dict
        Per model: ``max`` k-hat, the ArviZ ``threshold`` for this sample size,
        and ``n_bad`` ranges above it.
    shifts : dict
        For ``d0`` and ``sigma_mp``: both intervals, the shift of the mean and of
        each interval end (learned minus equal), and the width ratio.
    changed : pandas.DataFrame
        Ranges whose most probable class differs: ``row`` (input position),
        ``equal``, ``learned`` and both probability vectors.
    """

    beacon: str
    equal: PosteriorResult = field(repr=False)
    learned: PosteriorResult = field(repr=False)
    elpd: dict
    elpd_diff: float
    elpd_diff_se: float
    pareto_k: dict
    shifts: dict
    changed: pd.DataFrame = field(repr=False)

    @property
    def verdict(self) -> str:
        """``"learned"`` or ``"equal"`` if the ELPD difference exceeds 2 SE and 4 nats, or not."""
        if abs(self.elpd_diff) <= max(CLEAR * self.elpd_diff_se, MIN_DIFF):
            return "no clear difference"
        return "learned" if self.elpd_diff > 0 else "equal"

    def to_dict(self) -> dict:
        """JSON-ready summary (the ``compare.json`` entry of this beacon)."""
        return {
            "elpd_equal": self.elpd["equal"][0], "elpd_equal_se": self.elpd["equal"][1],
            "elpd_learned": self.elpd["learned"][0], "elpd_learned_se": self.elpd["learned"][1],
            "elpd_diff": self.elpd_diff, "elpd_diff_se": self.elpd_diff_se,
            "verdict": self.verdict, "pareto_k": self.pareto_k, "shifts": self.shifts,
            "n_changed": int(len(self.changed)),
            "changed": self.changed.to_dict(orient="records")[:50],
            "weights_learned": self.learned.summary["weights"],
            "em_d0": float(self.learned.em.d0),
        }


def _shift(eq: dict, le: dict) -> dict:
    """Both intervals of one parameter, the shifts of its mean and ends, the width ratio."""
    (el, eh), (ll, lh) = eq["interval"], le["interval"]
    return {"equal": {"mean": eq["mean"], "interval": [el, eh]},
            "learned": {"mean": le["mean"], "interval": [ll, lh]},
            "mean_shift": le["mean"] - eq["mean"], "lower_shift": ll - el,
            "upper_shift": lh - eh,
            "width_ratio": (lh - ll) / (eh - el) if eh > el else float("nan")}


def compare_beacon(data: BeaconData, *, rng: RNGLike = None, learned_init=None,
                   **kwargs) -> PriorComparison:
    """Sample one beacon under equal and learned priors and compare them.

    Parameters
    ----------
    data : BeaconData
    rng : None, int or numpy.random.Generator
    learned_init : EMResult, optional
        The learned-weights EM fit to start the learned run from (e.g. the one
        :func:`~bayes_mpem.lbl.em.path_choice.choose_path` made), instead of fitting it again.
    **kwargs
        Passed to :func:`~bayes_mpem.lbl.bayes.beacon_sampling.sample_beacon` for both runs.

    Returns
    -------
    PriorComparison
    """
    gen = as_generator(rng)
    kwargs["log_likelihood"] = True  # LOO needs it
    eq = sample_beacon(data, priors="equal", rng=gen, **kwargs)
    le = sample_beacon(data, priors="learned", rng=gen,
                       **({"init": learned_init} if learned_init is not None else {}), **kwargs)
    loo_eq, loo_le = psis_loo(eq), psis_loo(le)
    diff_i = loo_le.elpd_i - loo_eq.elpd_i
    n = diff_i.size
    pk = {name: {"max": float(np.nanmax(loo.pareto_k, initial=-np.inf)),
                 "threshold": loo.good_k,
                 "n_bad": int(np.sum(loo.pareto_k > loo.good_k)),
                 "n_tied_tail": loo.n_constant}
          for name, loo in (("equal", loo_eq), ("learned", loo_le))}
    lab_eq, lab_le = eq.labels, le.labels
    ch = np.flatnonzero(lab_eq != lab_le)
    changed = pd.DataFrame({
        "row": data.rows[ch], "equal": lab_eq[ch], "learned": lab_le[ch],
        **{f"equal_p_{c}": eq.class_probs[ch, j] for j, c in enumerate(("dp", "mp", "ol"))},
        **{f"learned_p_{c}": le.class_probs[ch, j] for j, c in enumerate(("dp", "mp", "ol"))},
    })
    return PriorComparison(
        beacon=data.beacon, equal=eq, learned=le,
        elpd={"equal": (loo_eq.elpd, loo_eq.se), "learned": (loo_le.elpd, loo_le.se)},
        elpd_diff=float(diff_i.sum()), elpd_diff_se=float(np.sqrt(n * np.var(diff_i))),
        pareto_k=pk,
        shifts={k: _shift(eq.summary[k], le.summary[k]) for k in ("d0", "sigma_mp")},
        changed=changed)
