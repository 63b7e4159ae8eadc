"""What a command writes and prints at its end: the result's files, its figures, ``wrote`` lines."""

from __future__ import annotations


def write_result(result, out, *, figures: bool = True, **write) -> list:
    """Write ``result`` into ``out`` (``write`` its keywords), then its figures if asked.

    Returns the paths written; the figures come from :func:`bayes_mpem.report.write_figures`,
    imported only when drawn (``fit`` starts without matplotlib).
    """
    paths = list(result.write(out, **write).values())
    if figures:
        from ..report import write_figures

        paths += write_figures(result, out)
    return paths


def print_written(paths) -> None:
    """Print ``wrote PATH`` for each path."""
    for p in paths:
        print(f"wrote {p}")
