"""Progress of a sampling run: a bar on a terminal, plain lines in a log file.

:func:`run_ensemble` reports after every block of steps to a :class:`SamplingProgress`.
On a terminal it draws a tqdm bar whose total is the number of steps the stopping rule
is expected to need (re-estimated at each check from the autocorrelation time, capped
at ``max_steps``), with the ESS against its target beside it. When standard error is
not a terminal (a log file, a batch job) it prints one line instead, at the first
check, then at most every :data:`LOG_INTERVAL` seconds, and at the end::

    [sampler] beacon 4 (learned priors): step 250 of ~4250 (cap 20000), ESS 64 of 1000,
    tau 21, 0.6 s
    [sampler] beacon 4 (learned priors): done, 4250 steps, ESS 1012 (bulk 1034) of 1000,
    8.6 s

(one line each, cut here).

``progress`` arguments everywhere (:func:`bayes_mpem.sample`, :func:`bayes_mpem.compare`,
:func:`~bayes_mpem.survey_in.location_sampling.locate_survey_bayes`, ...) take
``"auto"`` (the above), ``"bar"`` or True (a bar), ``"log"`` (lines), or False (silent).
"""

from __future__ import annotations

import math
import sys
import time

#: seconds between two progress lines when standard error is not a terminal
LOG_INTERVAL = 10.0
MODES = ("auto", "bar", "log")


def progress_mode(progress) -> str | None:
    """Resolve a ``progress`` argument to ``"bar"``, ``"log"`` or None (silent).

    Parameters
    ----------
    progress : bool, None or {"auto", "bar", "log"}
        ``"auto"``: a bar when standard error is a terminal, lines otherwise; True is
        ``"bar"``; False or None is silent.

    Returns
    -------
    str or None

    Raises
    ------
    ValueError
        For any other value.

    Examples
    --------
    >>> progress_mode(False) is None, progress_mode("log")
    (True, 'log')
    """
    if progress is None or progress is False:
        return None
    if progress is True:
        return "bar"
    if progress not in MODES:
        raise ValueError(f"progress: expected True, False or one of {MODES}, got {progress!r}")
    if progress == "auto":
        return "bar" if sys.stderr.isatty() else "log"
    return progress


def progress_bar(progress, desc: str, total: int | None = None):
    """Open a tqdm bar counting steps labelled ``desc``; None unless ``progress`` is a bar.

    Parameters
    ----------
    progress : bool, None or {"auto", "bar", "log"}
        As for :func:`progress_mode`; a bar only when it resolves to ``"bar"``.
    desc : str
        The bar's label.
    total : int, optional
        The expected number of steps.

    Returns
    -------
    tqdm.tqdm or None
    """
    if progress_mode(progress) != "bar":
        return None
    from tqdm.auto import tqdm

    return tqdm(desc=desc, total=total, unit="step", leave=False, file=sys.stderr)


class SamplingProgress:
    """Report one ensemble's run: a bar or log lines, by :func:`progress_mode`.

    Parameters
    ----------
    progress : bool, None or {"auto", "bar", "log"}
    label : str
        Names the run (e.g. ``"beacon 4 (learned priors)"``).
    n_walkers : int
    tau_factor, min_ess : float
        The stopping rule (:func:`~bayes_mpem.mcmc.driver.run_ensemble`).
    max_steps : int
        The step cap.
    check_every : int, default 1
        Steps between two checks of the stopping rule (the expected total is rounded up
        to a multiple of it).
    stream : file-like, optional
        Where the lines go (default: standard error).
    """

    def __init__(self, progress, label: str, *, n_walkers: int, tau_factor: float,
                 min_ess: float, max_steps: int, check_every: int = 1,
                 stream=None) -> None:
        self.mode = progress_mode(progress)
        self.label, self.n_walkers = label, int(n_walkers)
        self.tau_factor, self.min_ess, self.max_steps = tau_factor, min_ess, int(max_steps)
        self.check_every, self.stream = max(int(check_every), 1), stream
        self.t0 = self.last_line = time.perf_counter()
        self.lines = 0
        self.bar = progress_bar(self.mode, label, total=self.max_steps) if self.mode else None

    def expected_steps(self, burn: int, tau: float) -> int:
        """Return the steps the stopping rule needs at autocorrelation time ``tau``, capped.

        Parameters
        ----------
        burn : int
            The current burn-in (steps).
        tau : float
            The largest autocorrelation time on the kept chain (steps).

        Returns
        -------
        int
            ``burn + tau * max(tau_factor, min_ess / n_walkers)``, rounded up to a whole
            number of checks, at most ``max_steps`` (``max_steps`` while ``tau`` is not
            finite).

        Examples
        --------
        >>> p = SamplingProgress(False, "x", n_walkers=32, tau_factor=50, min_ess=1000,
        ...                      max_steps=20000)
        >>> p.expected_steps(40, 20.0)
        1040
        """
        if not math.isfinite(tau):
            return self.max_steps
        need = burn + tau * max(self.tau_factor, self.min_ess / self.n_walkers)
        need = math.ceil(need / self.check_every) * self.check_every
        return int(min(self.max_steps, need))

    def update(self, step: int, burn: int, tau: float) -> None:
        """Report the state after ``step`` steps.

        Parameters
        ----------
        step : int
            Steps run so far.
        burn : int
            The current burn-in.
        tau : float
            The largest autocorrelation time on the kept chain (inf before there is one).
        """
        if self.mode is None:
            return
        kept = max(step - burn, 0)
        ess = kept * self.n_walkers / tau if math.isfinite(tau) and tau > 0 else 0.0
        total = max(self.expected_steps(burn, tau), step)
        if self.bar is not None:
            self.bar.total = total
            self.bar.update(step - self.bar.n)
            self.bar.set_postfix_str(f"ESS {ess:.0f}/{self.min_ess:g}, tau {tau:.0f}")
            return
        now = time.perf_counter()
        if self.lines and now - self.last_line < LOG_INTERVAL:
            return
        self._say(f"step {step} of ~{total} (cap {self.max_steps}), ESS {ess:.0f} of "
                  f"{self.min_ess:g}, tau {tau:.0f}, {now - self.t0:.1f} s")
        self.last_line = now

    def close(self) -> None:
        """Close the bar (if any); :meth:`finish` prints the last line."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def finish(self, *, step: int, converged: bool, ess: float, ess_bulk: float | None) -> None:
        """Print the last line (log mode) and close the bar.

        Parameters
        ----------
        step : int
            Steps run.
        converged : bool
            Whether the stopping rule was met.
        ess : float
            The smallest ESS by emcee's estimate.
        ess_bulk : float or None
            The smallest ArviZ bulk ESS (None when the run never got far enough to need it).
        """
        self.close()
        if self.mode != "log":
            return
        how = "done" if converged else f"stopped at max_steps={self.max_steps}"
        bulk = "" if ess_bulk is None else f" (bulk {ess_bulk:.0f})"
        self._say(f"{how}, {step} steps, ESS {ess:.0f}{bulk} of {self.min_ess:g}, "
                  f"{time.perf_counter() - self.t0:.1f} s")

    def _say(self, text: str) -> None:
        say(self.label, text, self.stream)
        self.lines += 1


def say(label: str, text: str, stream=None) -> None:
    """Print one progress line, ``[sampler] <label>: <text>``, on ``stream`` (standard error).

    Parameters
    ----------
    label : str
        Names the posterior.
    text : str
    stream : file-like, optional
    """
    print(f"[sampler] {label}: {text}", file=stream or sys.stderr, flush=True)
