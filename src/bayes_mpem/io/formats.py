"""The survey file formats by name, format sniffing, and the sample surveys shipped."""

from __future__ import annotations

import re
from pathlib import Path

from .._validate import check_choice
from ..exceptions import InputError
from .garpos import read_garpos
from .gnatss import read_gnatss
from .obsrange import read_obsrange_sio, read_obsrange_whoi
from .raw import RawSurvey
from .seagap import read_seagap

FORMATS = ("obsrange-sio", "obsrange-whoi", "seagap", "garpos", "gnatss")
_READERS = {"obsrange-sio": read_obsrange_sio, "obsrange-whoi": read_obsrange_whoi,
            "seagap": read_seagap, "garpos": read_garpos, "gnatss": read_gnatss}


def sample_file(name: str) -> Path:
    """Path of a measured sample survey shipped with the package (``data/README.md``).

    Parameters
    ----------
    name : str
        Path relative to the sample folder, e.g. ``"obsrange/SIO_CC03.txt"``.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        If there is no such sample.
    """
    here = Path(__file__).resolve().parents[1]  # the bayes_mpem package
    for root in (here / "_samples", here.parents[1] / "data"):
        if (root / name).is_file():
            return root / name
    raise FileNotFoundError(f"no sample file {name!r} (expected e.g. 'obsrange/SIO_CC03.txt' or "
                            "'seagap/obsdata.inp')")


def _first_lines(path, n=40):
    lines = []
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        for line in fh:
            if line.strip():
                lines.append(line.strip())
            if len(lines) >= n:
                break
    return lines


def sniff_format(path) -> str:
    """Recognise a survey file's format (one of :data:`FORMATS`) from its first lines.

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    str

    Raises
    ------
    FileNotFoundError, InputError
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"survey file {str(path)!r} is a folder; expected a file")
    if not path.is_file():
        raise FileNotFoundError(f"survey file not found: {str(path)!r}")
    lines = _first_lines(path)
    if any(re.fullmatch(r"\[(Site|Obs|Model)-parameter\]", s) for s in lines):
        return "garpos"
    if any(re.match(r"^solver\s*:", s) for s in lines) and not any("msec." in s for s in lines):
        return "gnatss"
    if lines and lines[0].startswith("#") and any("," in s and not s.startswith("#")
                                                  for s in lines):
        return "obsrange-whoi"
    if any(re.search(r"\d\s*msec\.", s) for s in lines) or any(
            s.lower().startswith(("drop point", "ranging data taken")) for s in lines):
        return "obsrange-sio"
    data = [s for s in lines if not s.startswith("#")]
    if data and 2 * sum(len(s.split()) == 18 for s in data[:5]) > len(data[:5]):  # one bad line
        return "seagap"
    raise InputError(f"{path}: not a survey format bayes-mpem recognises (tried "
                     f"{', '.join(FORMATS)}); give --format")


def read_survey(path, format: str = "auto", **kwargs) -> RawSurvey:
    """Read a survey file of the given ``format`` (one of :data:`FORMATS`, or ``"auto"``).

    Parameters
    ----------
    path : str or pathlib.Path
    format : {"auto", "obsrange-sio", "obsrange-whoi", "seagap", "garpos", "gnatss"}
    **kwargs
        Passed to the reader.

    Returns
    -------
    RawSurvey

    Raises
    ------
    FileNotFoundError, InputError
    """
    check_choice("format", format, ("auto", *FORMATS))
    if format == "auto":
        format = sniff_format(path)
    return _READERS[format](path, **kwargs)
