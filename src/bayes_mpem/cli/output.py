"""What a command writes and prints at its end: the result's files, its figures, ``wrote`` lines."""

from __future__ import annotations


def write_result(result, out, *, figures: bool = True, table_format=None, **draw) -> list:
    """Write ``result`` into ``out``, then its figures if asked; return the paths written.

    ``table_format`` goes to ``result.write``, ``draw`` to :func:`bayes_mpem.report.write_figures`
    (imported only when drawn: ``fit`` starts without matplotlib).
    """
    paths = list(result.write(out, **({} if table_format is None else
                                      {"table_format": table_format})).values())
    if figures:
        from ..report import write_figures

        paths += write_figures(result, out, **draw)
    return paths


def print_written(paths) -> None:
    """Print ``wrote PATH`` for each path."""
    for p in paths:
        print(f"wrote {p}")
