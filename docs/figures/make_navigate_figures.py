"""Draw the figures of docs/navigate.md and docs/stream.md from one seeded simulated dive.

Run from the repository root: ``python docs/figures/make_navigate_figures.py`` (about 20 s).
The figures are the package's own (:mod:`bayes_mpem.plots.navigate`); the stream figure
draws the online filter's answers over the batch smoother's correction.
"""

import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from bayes_mpem.lbl.navigate import navigate, simulate_dive  # noqa: E402
from bayes_mpem.lbl.navigate.online import Navigator  # noqa: E402
from bayes_mpem.plots.navigate import (  # noqa: E402
    plot_nav_correction,
    plot_nav_ranges,
    plot_nav_track,
)

OUT = Path(__file__).parent


def main():
    sim = simulate_dive("abe58", rng=4, n_cycles=700)
    truth = sim.true_track
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nav = navigate(sim.survey, rng=0)
    for name, fig in (("navigate_track", plot_nav_track(nav, truth=truth)),
                      ("navigate_ranges", plot_nav_ranges(nav)),
                      ("navigate_correction", plot_nav_correction(nav, truth=truth))):
        fig.savefig(OUT / f"{name}.png", dpi=80)
        plt.close(fig)
    # the stream: the online filter fed 40 lines at a time, as `bayes-mpem stream` reads them
    table, beacons = sim.survey.table, sim.survey.beacons.reset_index()
    online = Navigator(beacons, rng=0)
    answers = pd.concat([online.run(table.iloc[s:s + 40]) for s in range(0, len(table), 40)],
                        ignore_index=True)
    keep = (answers["phase"] == "online").to_numpy()
    fig = plot_nav_correction(nav, truth=truth)
    for ax, col in zip(fig.axes, ("x", "y"), strict=True):
        corr = answers[col].to_numpy() - table[col].to_numpy()  # the pings' x, y: dead reckoned
        ax.plot(answers["time"][keep], corr[keep], color="tab:green", lw=0.6,
                label="online filter (stream)")
    fig.axes[0].legend(loc="upper left", fontsize="small")
    fig.axes[0].set_title("correction to the dead reckoning: the stream's online answers "
                          "against the batch smoother", fontsize="medium")
    fig.savefig(OUT / "stream_correction.png", dpi=80)
    plt.close(fig)

if __name__ == "__main__":
    main()
