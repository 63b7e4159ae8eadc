"""The survey file formats by name, and the sample surveys shipped with the package.

:func:`read_survey` dispatches a path to the reader of one of :data:`FORMATS`
(:mod:`bayes_mpem.io.obsrange`, :mod:`bayes_mpem.io.seagap`), and
:func:`sample_file` finds a measured sample survey.
"""

from __future__ import annotations

from pathlib import Path

from .._validate import check_choice
from .obsrange import read_obsrange_sio, read_obsrange_whoi
from .raw import RawSurvey
from .seagap import read_seagap

FORMATS = ("obsrange-sio", "obsrange-whoi", "seagap")


def sample_file(name: str) -> Path:
    """Path of a measured sample survey shipped with the package.

    The OBSrange samples (``"obsrange/SIO_CC03.txt"``, ``SIO_EC03.txt``,
    ``SIO_WC03.txt``, ``WHOI_S05.txt``, ``CC03_ssp.txt``,
    ``CC03_obsrange_solution.txt``) and the SeaGap example (``"seagap/obsdata.inp"``
    with its companion files); their sources and licences are in the ``README.md``
    beside them (``data/README.md`` in the source repository).

    Parameters
    ----------
    name : str
        Path relative to the sample folder.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        If there is no such sample.

    Examples
    --------
    >>> sample_file("obsrange/SIO_CC03.txt").name
    'SIO_CC03.txt'
    """
    here = Path(__file__).resolve().parents[1]  # the bayes_mpem package
    for root in (here / "_samples", here.parents[1] / "data"):
        if (root / name).is_file():
            return root / name
    raise FileNotFoundError(f"no sample file {name!r} (expected e.g. 'obsrange/SIO_CC03.txt' or "
                            "'seagap/obsdata.inp')")


def read_survey(path, format: str, **kwargs) -> RawSurvey:
    """Read a survey file of the given ``format`` (one of :data:`FORMATS`).

    Parameters
    ----------
    path : str or pathlib.Path
    format : {"obsrange-sio", "obsrange-whoi", "seagap"}
    **kwargs
        Passed to the reader (``strict``; SeaGap companion paths).

    Returns
    -------
    RawSurvey
    """
    readers = {"obsrange-sio": read_obsrange_sio, "obsrange-whoi": read_obsrange_whoi,
               "seagap": read_seagap}
    check_choice("format", format, FORMATS)
    return readers[format](path, **kwargs)
