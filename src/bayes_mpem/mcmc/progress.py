"""Progress of a sampling run: a bar on a terminal, plain lines in a log (``docs/bayes.md``)."""

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


def _progress_bar(progress, desc: str, total: int | None = None):
    """Open a tqdm bar counting steps labelled ``desc``; None unless ``progress`` is a bar."""
    if progress_mode(progress) != "bar":
        return None
    from tqdm.auto import tqdm

    return tqdm(desc=desc, total=total, unit="step", leave=False, file=sys.stderr)


class SamplingProgress:
    """Report a run of :func:`~bayes_mpem.mcmc.driver.run_ensembles`: a bar or log lines.

    Parameters
    ----------
    progress : bool, None or {"auto", "bar", "log"}
        As for :func:`progress_mode`.
    label : str
        Names the run (e.g. ``"beacon 4 (learned priors)"``).
    min_ess, max_rhat : float
        The stopping rule.
    max_steps : int
        The step cap.
    n_walkers : int
        Walkers over all ensembles.
    stream : file-like, optional
        Where the lines go (default: standard error).
    """

    def __init__(self, progress, label: str, *, min_ess: float, max_rhat: float,
                 max_steps: int, n_walkers: int, stream=None) -> None:
        self.mode = progress_mode(progress)
        self.label, self.n_walkers = label, int(n_walkers)
        self.min_ess, self.max_rhat, self.max_steps = min_ess, max_rhat, int(max_steps)
        self.stream = stream
        self.t0 = self.last_line = time.perf_counter()
        self.lines = 0
        self.bar = _progress_bar(self.mode, label, total=self.max_steps) if self.mode else None

    def _rule(self, ess: float, rhat: float) -> str:
        return (f"ESS {_count(ess)}, target {_count(self.min_ess)}; R-hat {rhat:.3f}, "
                f"target < {self.max_rhat:g}")

    def update(self, step: int, ess: float, rhat: float, *, expected: float) -> None:
        """Report the state after ``step`` steps.

        Parameters
        ----------
        step : int
            Steps run so far.
        ess, rhat : float
            The smallest bulk ESS and largest R-hat of the kept chain.
        expected : float
            Steps the stopping rule is expected to need.
        """
        if self.mode is None:
            return
        total = int(min(self.max_steps, max(step, math.ceil(expected))))
        if self.bar is not None:
            self.bar.total = total
            self.bar.update(step - self.bar.n)
            self.bar.set_postfix_str(self._rule(ess, rhat))
            return
        now = time.perf_counter()
        if self.lines and now - self.last_line < LOG_INTERVAL:
            return
        self._say(f"step {_count(step)} of ~{_count(total)}: {self._rule(ess, rhat)}; "
                  f"{now - self.t0:.1f} s")
        self.last_line = now

    def close(self) -> None:
        """Close the bar (if any); :meth:`finish` prints the last line."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def finish(self, *, steps: int, converged: bool, ess: float, rhat: float) -> None:
        """Print the last line (log mode) and close the bar.

        Parameters
        ----------
        steps : int
            Steps run.
        converged : bool
            Whether the stopping rule was met.
        ess, rhat : float
            The smallest bulk ESS and largest R-hat at the end.
        """
        self.close()
        if self.mode != "log":
            return
        how = "done" if converged else f"stopped at max_steps={_count(self.max_steps)}"
        self._say(f"{how}, {_count(steps)} steps x {self.n_walkers} walkers: "
                  f"{self._rule(ess, rhat)}; {time.perf_counter() - self.t0:.1f} s")

    def _say(self, text: str) -> None:
        say(self.label, text, self.stream)
        self.lines += 1


def _count(x: float) -> str:
    """Format a count with thousands separators (``1,307``), ``inf`` as is."""
    return f"{x:,.0f}" if math.isfinite(x) else f"{x}"


def say(label: str, text: str, stream=None) -> None:
    """Print one progress line, ``[sampler] <label>: <text>``, on ``stream`` (standard error).

    Parameters
    ----------
    label : str
    text : str
    stream : file-like, optional
    """
    print(f"[sampler] {label}: {text}", file=stream or sys.stderr, flush=True)
