"""The error the command line raises for options that do not go together.

Examples
--------
>>> isinstance(OptionError("--pol applies to --method paper only"), ValueError)
True
"""

from __future__ import annotations


class OptionError(ValueError):
    """An option that does not apply to the chosen method or mode.

    :func:`~bayes_mpem.cli.main` reports it as ``bayes-mpem COMMAND:
    error: MESSAGE`` with exit status 2, as any other invalid value.
    """
