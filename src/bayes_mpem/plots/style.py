"""The class colours, the colour key and the labels shared by every figure."""

from __future__ import annotations

import contextlib

import numpy as np

#: class -> RGB of each palette; ``mp2`` is the diagnosis' second reflector
PALETTES: dict[str, dict[str, tuple[float, float, float]]] = {
    "okabe-ito": {"dp": (0.0, 0.447, 0.698), "mp": (0.835, 0.369, 0.0),
                  "mp2": (0.8, 0.475, 0.655), "ol": (0.6, 0.6, 0.6)},
    "paper": {"dp": (0.0, 0.0, 1.0), "mp": (1.0, 0.0, 0.0), "mp2": (0.5, 0.0, 0.5),
              "ol": (0.0, 1.0, 0.0)},
}
DEFAULT_PALETTE = "okabe-ito"
#: the words for the classes on figures
CLASS_NAMES = {"dp": "direct path", "mp": "multipath", "mp2": "second multipath",
               "ol": "outlier"}
#: axis labels of the parameters, the same on every figure
PARAM_LABELS = {"d0": "d0 (m)", "sigma_mp": "sigma_MP (m)", "sigma_dp": "sigma_DP (m)",
                "w_dp": "w_dp", "w_mp": "w_mp", "w_ol": "w_ol"}

_current = {"palette": DEFAULT_PALETTE}


def use_palette(name: str) -> str:
    """Draw the class colours of every later figure with palette ``name``; return the one before.

    Raises
    ------
    ValueError
    """
    if name not in PALETTES:
        raise ValueError(f"palette: expected one of {tuple(PALETTES)}, got {name!r}")
    old, _current["palette"] = _current["palette"], name
    return old


@contextlib.contextmanager
def palette_context(name: str):
    """Use the palette ``name`` inside a ``with`` block, and the previous one after it.

    Yields
    ------
    str
        ``name``.
    """
    old = use_palette(name)
    try:
        yield name
    finally:
        use_palette(old)


def class_color(name: str, palette: str | None = None) -> tuple[float, float, float]:
    """Return the RGB colour (in [0, 1]) of one class.

    Parameters
    ----------
    palette : str, optional
        Default: the one in use.
    """
    return PALETTES[palette or _current["palette"]][name]


def class_colors(resp, palette: str | None = None):
    """RGB colours of class probabilities: each class's colour weighted by its probability.

    Parameters
    ----------
    resp : array_like
        ``(n, 3)`` probabilities of dp, mp, ol.
    palette : str, optional
        Default: the one in use (``"paper"``: red = p_mp, green = p_ol, blue = p_dp).

    Returns
    -------
    numpy.ndarray
    """
    resp = np.clip(np.asarray(resp, float), 0.0, 1.0)
    base = np.array([class_color(c, palette) for c in ("dp", "mp", "ol")])
    return np.clip(resp @ base, 0.0, 1.0)


def class_key(ax, classes=("dp", "mp", "ol"), *, extra=(), where=None, **kwargs):
    """Add the colour key of the classes to a figure's legend.

    Parameters
    ----------
    ax : matplotlib.axes.Axes or matplotlib.figure.Figure
        A figure gets one legend for all its panels, above them.
    extra : sequence of matplotlib.artist.Artist
        Further handles (with labels) after the classes.
    where : str, optional
        The legend's ``loc``.
    **kwargs
        Passed to ``legend``.
    """
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], ls="none", marker="o", ms=5, color=class_color(c),
                      label=CLASS_NAMES[c]) for c in classes]
    handles += list(extra)
    is_fig = not hasattr(ax, "transData")
    loc = where or ("outside upper center" if is_fig else "upper right")
    kwargs.setdefault("fontsize", "small")
    kwargs.setdefault("ncol", len(handles) if is_fig else 1)
    return ax.legend(handles=handles, loc=loc, **kwargs)


def plain_log_axis(axis) -> None:
    """Label a log axis with plain numbers (``7``, ``10``, ``20``), never ``7x10^0``.

    Parameters
    ----------
    axis : matplotlib.axis.Axis
        E.g. ``ax.yaxis`` of a ``semilogy`` plot.
    """
    from matplotlib.ticker import FuncFormatter, LogLocator

    def minor(v, _):
        lo, hi = sorted(axis.get_view_interval())
        return f"{v:g}" if lo > 0 and hi / lo < 10 else ""

    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(FuncFormatter(minor))


#: Colours of a survey-in's ping classes (Okabe-Ito blue and vermillion: told apart with
#: every common colour-vision deficiency), and of lines that were not pings.
SURVEY_IN_COLORS = {"true": "#0072B2", "spurious": "#D55E00", "skipped": "#999999"}
#: Markers of the same classes, so that the figures read in grey too.
SURVEY_IN_MARKERS = {"true": "o", "spurious": "X", "skipped": "."}
