"""What users see (issue 25, item 5): every quality flag of summary.json is printed under
the console table, and the advice names options the command line offers."""

import re
import warnings

import numpy as np
import pytest

from bayes_mpem.cli.parser import build_parser
from bayes_mpem.exceptions import ConvergenceWarning, NavigationWarning
from bayes_mpem.lbl.navigate import navigate, simulate_dive
from bayes_mpem.lbl.navigate.result import quality_lines
from bayes_mpem.lbl.navigate.simulate import simulate_ship


def _quiet(*tables, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NavigationWarning)
        return navigate(*tables, rng=0, **kw)


@pytest.fixture(scope="module")
def navs():
    ship = simulate_ship(rng=0, n_cycles=300)
    dive = simulate_dive("abe58", rng=2, n_cycles=150)
    one = dive.survey.table[dive.survey.table["beacon"] == dive.survey.table["beacon"].iloc[0]]
    return [_quiet(ship.survey), _quiet(dive.survey),
            _quiet(one, dive.survey.beacons.reset_index())]


def _bounds(node, path=()):
    """Every record marked at_bound (a beacon's sigma_DP repeats the shared one)."""
    if isinstance(node, dict):
        if node.get("at_bound") is True:
            yield path
        for k, v in node.items():
            if not (k == "sigma_dp" and path):
                yield from _bounds(v, (*path, k))


def _check_printed(summary, text):
    for bid, b in summary["beacons"].items():
        for f in b.get("flags") or ():
            assert f"beacon {bid}: {f}" in text
        if b.get("reason"):
            assert f"beacon {bid}: {b['reason']}" in text
    for f in summary["observability"]:
        assert f["reason"] in text
    assert f"intervals from the {summary['information']} information" in text
    for bid, why in summary["skipped"].items():
        assert why in text
    for f in (summary.get("model_checks") or {}).get("flags", ()):
        assert f"model check, {f}" in text
    paths = list(_bounds(summary))
    assert text.count("(one-sided interval)") == len(paths)
    for path in paths:
        assert path[-1] in text or path == ("sigma_dp",)


def test_every_flag_of_real_summaries_is_printed(navs):
    for nav in navs:
        s = nav.summary()
        _check_printed(s, nav.format_table())
    # the single beacon: not corrected, said on the console
    assert navs[2].summary()["observability"]
    assert "navigation not corrected" in navs[2].format_table()


def test_every_bound_anywhere_in_the_summary_is_printed(navs):
    s = navs[1].summary()
    bid = next(iter(s["beacons"]))
    b = s["beacons"][bid]
    marked = {"estimate": 0.0, "sd": 0.1, "interval": [0.0, 0.16], "at_bound": True}
    b["d0"] = b["sigma_mp"] = b["weights"]["ol"] = dict(marked)
    s["sigma_dp"] = dict(marked)
    s["dead_reckoning"]["speed_scale"] = dict(marked)
    s["range_scale"] = dict(marked)
    s["converged"] = False
    s["skipped"] = {"9": "beacon 9 has no reply"}
    s["model_checks"] = {**(s.get("model_checks") or {}), "flags": ["beacon 1: mean residual"]}
    lines = quality_lines(s)
    text = "\n".join(lines)
    _check_printed(s, text)
    for what in (f"beacon {bid}: d0 at its bound", f"beacon {bid}: sigma_mp at its bound",
                 f"beacon {bid}: weight of ol at its bound", "sigma_DP at its floor",
                 "dead_reckoning speed_scale at its bound", "range_scale at its bound",
                 "did NOT converge", "beacon 9 skipped"):
        assert what in text, what


def test_a_switched_off_class_weight_is_fixed_not_at_a_bound(navs):
    s = navs[0].summary()  # the ship: no multipath class anywhere
    for b in s["beacons"].values():
        assert b["weights"]["mp"]["fixed"] and "at_bound" not in b["weights"]["mp"]


def test_advice_names_options_the_command_offers():
    sim = simulate_dive("abe58", rng=1, n_cycles=60)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        nav = navigate(sim.survey, rng=0, max_iter=2)
    msg = [str(w.message) for w in caught if issubclass(w.category, ConvergenceWarning)]
    assert msg
    text = "\n".join(msg + quality_lines(nav.summary()))
    named = set(re.findall(r"--[a-z][a-z-]+", text))
    assert {"--max-iter", "--tol"} <= named
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    offered = {o for a in sub.choices["navigate"]._actions for o in a.option_strings}
    assert named <= offered, named - offered
    assert not np.isnan(nav.loglik)
