"""Shared by the benchmark scripts: each owns one marked section of a Markdown file."""

from __future__ import annotations

import os
import platform
import subprocess
from pathlib import Path

import numpy as np

HEADER = "# Benchmarks\n\nEach section is written by the script it names; rerun it to refresh it.\n"


def machine() -> str:
    """One line describing this machine and the numeric stack."""
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{os.cpu_count()} cores, {cpu}, Python {platform.python_version()}, "
            f"NumPy {np.__version__}")


def commit() -> str:
    """The checkout's short commit (``+ changes`` where ``src/`` or ``benchmarks/`` differ).

    ``unknown`` outside a git checkout.
    """
    here = Path(__file__).resolve().parent
    try:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here,
                             capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "../src", "."], cwd=here,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return f"{rev} + changes" if dirty else rev


def write_section(path, name: str, text: str) -> None:
    """Replace (or append) the section ``name`` of the Markdown file ``path``."""
    path = Path(path)
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    old = path.read_text() if path.exists() else HEADER
    block = f"{start}\n{text.rstrip()}\n{end}"
    if start in old and end in old:
        new = old[: old.index(start)] + block + old[old.index(end) + len(end):]
    else:
        new = old.rstrip() + "\n\n" + block + "\n"
    path.write_text(new)
