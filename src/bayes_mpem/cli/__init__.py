"""The ``bayes-mpem`` command line: parse, call the library, report.

:mod:`.parser` builds the parser and dispatches; :mod:`.lbl` and
:mod:`.survey_in` hold one ``cmd_*`` function per sub-command of each wing;
:mod:`.errors` the option error.
"""

from .._deprecated import moved_attribute
from .parser import build_parser, main

__all__ = ["build_parser", "main"]

# the sub-command functions lived in the old single ``bayes_mpem.cli`` module
_MOVED = {**{f"cmd_{c}": "cli.lbl" for c in ("demo", "plot", "simulate", "fit", "sample",
                                             "compare", "diagnose")},
          "cmd_locate": "cli.survey_in"}


def __getattr__(name):
    if name in _MOVED:
        return moved_attribute(__name__, name, _MOVED[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
