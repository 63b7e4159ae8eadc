"""What locating the transponders of a survey returns, and the files it writes.

:class:`SurveyInResult` holds the JSON-ready summary and the per-line
classification of :func:`~.survey.locate_survey` (and of
:func:`~.location_sampling.locate_survey_bayes`, which returns the same pair
with posterior intervals), and writes ``summary.json`` and ``classified.csv``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import pandas as pd

from ..io.results import write_csv, write_json, writing


@dataclass(frozen=True)
class SurveyInResult:
    """Every transponder of a survey, located.

    Attributes
    ----------
    summary : dict
        ``{"transponders": {id: {"lat", "lon", "depth", "sound_speed", ...}}, ...}``
        (the content of ``summary.json``).
    classified : pandas.DataFrame
        One row per ping line and per skipped line of the file, in file order:
        ``line``, ``transponder``, ``twtt``, ``p_true``, ``p_spurious``, ``label``
        (``true``, ``spurious`` or ``skipped``) and ``reason``.
    posteriors : dict
        ``{id: LocationPosterior}`` when the posterior was sampled, else empty.
    fits : dict
        ``{id: LocateResult}``, the EM fit of each transponder (not written).

    Notes
    -----
    Unpacking, ``summary, classified = locate_survey(raw)``, still works for
    code written when :func:`~.survey.locate_survey` returned a pair, with a
    :class:`DeprecationWarning`; use the attributes instead.

    Examples
    --------
    >>> import pandas as pd
    >>> res = SurveyInResult({"transponders": {}}, pd.DataFrame({"line": [1]}))
    >>> res.to_dict()
    {'transponders': {}}
    """

    summary: dict
    classified: pd.DataFrame
    posteriors: dict = field(default_factory=dict, repr=False)
    fits: dict = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        """Return the content of ``summary.json``.

        Returns
        -------
        dict
        """
        return self.summary

    def write(self, out_dir) -> dict:
        """Write ``summary.json`` and ``classified.csv`` to ``out_dir``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.

        Returns
        -------
        dict
            Paths written, keyed ``summary`` and ``classified``.
        """
        with writing(out_dir) as out:
            return {"classified": write_csv(out / "classified.csv", self.classified),
                    "summary": write_json(out / "summary.json", self.summary)}

    def _as_pair(self):
        warnings.warn("using the result of locate_survey as a (summary, classified) pair is "
                      "deprecated; use its .summary and .classified attributes",
                      DeprecationWarning, stacklevel=3)
        return (self.summary, self.classified)

    def __iter__(self):
        """Yield ``summary`` then ``classified`` (deprecated pair unpacking)."""
        return iter(self._as_pair())

    def __getitem__(self, index):
        """``summary`` at 0, ``classified`` at 1 (deprecated pair indexing)."""
        return self._as_pair()[index]
