"""The EM loop the mixture models of the package share (docs/architecture.md, "One EM loop").

A model (:class:`EMModel`) gives its E-step and M-step; :func:`run_em` owns the loop,
convergence, history, warning and final E-step, as scikit-learn's ``BaseMixture`` does.

References
----------
Dempster, A. P., Laird, N. M. and Rubin, D. B. (1977). Maximum likelihood from
incomplete data via the EM algorithm. *J. R. Stat. Soc. B* 39, 1-38.

Examples
--------
Two unit-variance Gaussians of equal weight, their means unknown:

>>> import numpy as np
>>> x = np.r_[np.zeros(50), np.full(50, 4.0)] + np.random.default_rng(0).normal(0, 0.5, 100)
>>> class TwoMeans(EMModel):
...     def e_step(self, mu):
...         logp = -0.5 * (x[:, None] - mu) ** 2
...         lse = np.logaddexp(logp[:, 0], logp[:, 1])
...         return float(lse.sum()), np.exp(logp - lse[:, None])
...     def m_step(self, mu, resp):
...         return resp.T @ x / resp.sum(axis=0)
>>> run = run_em(TwoMeans(), np.array([1.0, 2.0]), tol=1e-8, max_iter=100)
>>> run.converged, np.round(run.params, 1).tolist()
(True, [0.1, 4.0])
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..exceptions import ConvergenceWarning


class EMModel:
    """What a model gives :func:`run_em`: its E-step, its M-step and optional hooks.

    Subclasses override :meth:`e_step` and :meth:`m_step`; the other hooks default to a
    maximum-likelihood EM. The parameters are whatever object the two steps exchange.

    Attributes
    ----------
    final_e_step : bool
        True (default): return the probabilities of an E-step at the returned parameters;
        False: those the last M-step used.
    """

    final_e_step = True

    def e_step(self, params):
        """Return ``(loglik or None, class probabilities)`` at ``params``.

        Parameters
        ----------
        params : object

        Returns
        -------
        tuple
        """
        raise NotImplementedError

    def m_step(self, params, resp):
        """Return new parameters given the probabilities ``resp`` of the E-step at ``params``.

        Parameters
        ----------
        params : object
        resp : numpy.ndarray

        Returns
        -------
        object
        """
        raise NotImplementedError

    def change(self, old, new, gain):
        """Return the size of an iteration from ``old`` to ``new`` (default ``abs(gain)``).

        Parameters
        ----------
        old, new : object
        gain : float or None
            The log-likelihood gain, None for a model without one.

        Returns
        -------
        float
        """
        return abs(gain)

    def record(self, params, loglik, resp) -> dict:
        """Return the values the history keeps of a state (default its log-likelihood).

        Parameters
        ----------
        params : object
        loglik : float or None
        resp : numpy.ndarray

        Returns
        -------
        dict
        """
        return {} if loglik is None else {"loglik": loglik}

    def usable(self, params) -> bool:
        """Return whether an E-step is defined at ``params`` (default True).

        Parameters
        ----------
        params : object

        Returns
        -------
        bool
        """
        return True


@dataclass(frozen=True)
class EMRun:
    """One run of :func:`run_em`.

    Attributes
    ----------
    params : object
        The last parameters.
    resp : numpy.ndarray
        Class probabilities at ``params`` (see :attr:`EMModel.final_e_step`).
    loglik : float or None
        Log-likelihood of the last E-step.
    n_iter : int
        Iterations (M-steps) run.
    converged : bool
    history : dict of list
        :meth:`EMModel.record` of every state, index 0 being the start.
    first_resp : numpy.ndarray
        Class probabilities of the first E-step.
    """

    params: Any
    resp: Any = field(repr=False)
    loglik: float | None
    n_iter: int
    converged: bool
    history: dict = field(repr=False)
    first_resp: Any = field(repr=False)


def run_em(model: EMModel, init=None, *, tol: float, max_iter: int, resume: EMRun | None = None,
           warn: Callable[[EMRun], str] | None = None, category=ConvergenceWarning,
           stacklevel: int = 2) -> EMRun:
    """Run EM from ``init`` until an iteration changes less than ``tol``, or ``max_iter``.

    Parameters
    ----------
    model : EMModel
    init : object
        Starting parameters (ignored with ``resume``).
    tol : float
        Converged when :meth:`EMModel.change` of an iteration is below it.
    max_iter : int
        Most iterations, counting those of ``resume``.
    resume : EMRun, optional
        Continue this run: its iterations, history and first probabilities are kept.
    warn : callable, optional
        ``warn(run) -> message``, warned with (as ``category``, at ``stacklevel`` from the
        caller) when the run did not converge.
    category : type, default ConvergenceWarning
    stacklevel : int, default 2

    Returns
    -------
    EMRun
    """
    if resume is None:
        params, done = init, 0
        loglik, resp = model.e_step(params)
        first, history = resp, {}
        _append(history, model.record(params, loglik, resp))
    else:
        params, loglik, resp, done = resume.params, resume.loglik, resume.resp, resume.n_iter
        first, history = resume.first_resp, {k: list(v) for k, v in resume.history.items()}
    used, converged, it = resp, False, done
    for it in range(done + 1, max_iter + 1):
        new, used = model.m_step(params, resp), resp
        if not model.usable(new):
            params = new
            break
        new_loglik, resp = model.e_step(new)
        _append(history, model.record(new, new_loglik, resp))
        step = model.change(params, new, None if loglik is None else new_loglik - loglik)
        params, loglik = new, new_loglik
        if step < tol:
            converged = True
            break
    run = EMRun(params, resp if model.final_e_step else used, loglik, it, converged, history,
                first)
    if warn is not None and not converged:
        warnings.warn(warn(run), category, stacklevel=stacklevel + 1)
    return run


def _append(history, values):
    for k, v in values.items():
        history.setdefault(k, []).append(v)


def best_run(runs):
    """Return the run of ``runs`` with the highest log-likelihood (the first of equals).

    Parameters
    ----------
    runs : iterable of EMRun

    Returns
    -------
    EMRun
    """
    best = None
    for run in runs:
        if best is None or run.loglik > best.loglik:
            best = run
    return best
