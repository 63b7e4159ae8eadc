"""The ``bayes-mpem`` command line: parse, call the library, report."""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
