"""The error the command line raises for options that do not go together."""

from __future__ import annotations


class OptionError(ValueError):
    """An option that does not apply to the chosen method or mode (``error:``, status 2)."""
