"""The ``bayes-mpem`` command line: parse, call the library, report.

:mod:`.parser` builds the parser and dispatches; :mod:`.lbl` and
:mod:`.survey_in` hold one ``cmd_*`` function per sub-command of each wing;
:mod:`.errors` the option error.
"""

from .parser import build_parser, main

__all__ = ["build_parser", "main"]
