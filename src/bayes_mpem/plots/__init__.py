"""Figures. Plot functions take ``ax=``/``fig=`` and return the Figure; none runs a fit."""

from .lbl import (
    plot_classification,
    plot_colormap,
    plot_convergence,
    plot_pol_sensitivity,
    plot_ranges,
    plot_survey_classification,
    plot_table_ii,
    plot_track,
    table_ii_markdown,
)
from .style import class_colors

__all__ = ["class_colors", "plot_classification", "plot_colormap", "plot_convergence",
           "plot_pol_sensitivity", "plot_ranges", "plot_survey_classification", "plot_table_ii",
           "plot_track", "table_ii_markdown"]
