"""Malformed inputs and options, generated (Hypothesis) and catalogued (issue 15).

Whatever is broken, every command either exits 0 with rows in = rows out and finite
outputs, or exits 2 with a message naming the file, line, column or option, never a
traceback, and never leaves a complete-looking wrong folder. The judge is
``tests/catalogue.py``; the whole catalogue (470 + 546 cases) runs in
``benchmarks/malformed_catalogue.py``, a deterministic part of it here.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/, for catalogue
import catalogue  # noqa: E402

FUZZ = settings(max_examples=50, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return catalogue.make_base(tmp_path_factory.mktemp("base"), with_sample=False)


@pytest.fixture(scope="module")
def all_cases(base, tmp_path_factory):
    return catalogue.cases(base, tmp_path_factory.mktemp("cases"), sample=True)


def _assert_fine(outcome):
    assert outcome.verdict in ("ok", "refused"), (outcome.case.name, outcome.verdict,
                                                   outcome.problems, outcome.err[-500:])


def test_a_deterministic_part_of_the_catalogue(all_cases):
    chosen = [c for i, c in enumerate(all_cases)
              if c.command != "sample" and i % 9 == 0 or c.name in (
                  "sample:cell_range_1", "sample:--ci=1.5", "sample:b_duplicate",
                  "fit:valid", "locate:valid_sio", "plot:fit_valid")]
    assert len(all_cases) >= 250 and len(chosen) >= 40
    verdicts = [catalogue.run_case(c).verdict for c in chosen]
    for case, v in zip(chosen, verdicts, strict=True):
        assert v in ("ok", "refused"), case.name
    assert "ok" in verdicts and "refused" in verdicts


_values = st.one_of(
    st.sampled_from(["", "nan", "inf", "-1", "0", "1e300", "abc", "1,5", "1;5", "\f", "#",
                     '"', "1e-400", "9" * 40, "\u00e9", " 7 "]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00\n"),
            max_size=6))
_edits = st.lists(st.tuples(st.sampled_from(["cell", "blank", "comment", "junk", "drop_field",
                                             "duplicate", "truncate"]),
                            st.integers(0, 10_000), st.integers(0, 5), _values),
                  min_size=1, max_size=4)


def _corrupt(lines, edits):
    header, rows = lines[0], list(lines[1:])
    for kind, i, j, value in edits:
        k = i % len(rows)
        if kind == "cell":
            f = rows[k].split(",")
            f[j] = value
            rows[k] = ",".join(f)
        elif kind == "blank":
            rows.insert(k, " \t")
        elif kind == "comment":
            rows.insert(k, "# " + value)
        elif kind == "junk":
            rows.insert(k, value)
        elif kind == "drop_field":
            rows[k] = ",".join(rows[k].split(",")[:-1])
        elif kind == "duplicate":
            rows.insert(k, rows[k])
        else:
            rows = rows[: k + 1]
            rows[-1] = rows[-1][: j + 1]
    return "\n".join([header, *rows]) + "\n"


@FUZZ
@given(edits=_edits)
def test_fit_on_a_corrupted_table(base, tmp_path_factory, edits):
    d = tmp_path_factory.mktemp("fz")
    path = d / "p.csv"
    path.write_text(_corrupt(base.pings.read_text().splitlines(), edits))
    case = catalogue.Case("fuzz", "fit", ["fit", path, "--beacons", base.beacons, "--out",
                                          d / "o"], d / "o", catalogue.count_table_rows(path))
    _assert_fine(catalogue.run_case(case))


@FUZZ
@given(edits=st.lists(st.tuples(st.integers(0, 200), st.integers(0, 100), _values),
                      min_size=1, max_size=4))
def test_locate_on_a_corrupted_deck_box_log(base, tmp_path_factory, edits):
    lines = base.sio.read_text().splitlines()
    for i, pos, value in edits:
        k = i % len(lines)
        lines[k] = lines[k][:pos] + value + lines[k][pos + len(value):]
    d = tmp_path_factory.mktemp("fz")
    path = d / "s.txt"
    path.write_text("\n".join(lines) + "\n")
    case = catalogue.Case("fuzz", "locate", ["locate", path, "--format", "obsrange", "--out",
                                             d / "o"], d / "o", survey=path)
    _assert_fine(catalogue.run_case(case))


@FUZZ
@given(option=st.sampled_from([("fit", "--sigma-dp"), ("fit", "--min-pings"), ("fit", "--seed"),
                               ("diagnose", "--min-gain"), ("diagnose", "--folds"),
                               ("sample", "--ci"), ("sample", "--concentration"),
                               ("sample", "--ensembles"), ("locate", "--ci"),
                               ("locate", "--tat"), ("locate", "--speed-intervals")]),
       value=_values)
def test_any_option_value(base, tmp_path_factory, option, value):
    """An option value is accepted only when valid; the run is then checked as any other."""
    command, name = option
    d = tmp_path_factory.mktemp("fz")
    if command == "locate":
        argv = ["locate", base.sio, "--format", "obsrange"]
    else:
        argv = [command, base.pings, "--beacons", base.beacons]
    if command == "sample":
        argv += ["--min-pings", "100000", "--no-progress"]  # every beacon left out: no sampling
    if command == "diagnose":
        argv += ["--no-progress", "--no-figures", "--effects", "range_bias"]
    case = catalogue.Case("fuzz", command, [*argv, "--out", d / "o", f"{name}={value}"],
                          d / "o", catalogue.count_table_rows(base.pings)
                          if command != "locate" else None,
                          survey=base.sio if command == "locate" else None)
    _assert_fine(catalogue.run_case(case))


# --------------------------------------------------------------------------- issue 27


@pytest.fixture(scope="module")
def surfaces(tmp_path_factory):
    return catalogue.make_surfaces(tmp_path_factory.mktemp("surfaces"))


def test_a_deterministic_part_of_the_newer_surfaces(surfaces, tmp_path_factory):
    """navigate, stream (lines, replay, options, state), batch and GNSS-A: ok or refused."""
    cases = catalogue.surface_cases(surfaces, tmp_path_factory.mktemp("surface_cases"))
    assert len(cases) >= 350
    kinds = {c.kind or c.command for c in cases}
    assert kinds == {"navigate", "stream", "batch", "garpos", "gnatss"}
    must = {"stream:time_0", "stream:x_18", "stream:depth_21", "stream:replay_0_realtime",
            "stream:x_4", "stream:time_4", "stream:time_5",
            "stream:state_filter_cov_null", "stream:state_nan_token", "stream:bare_cr",
            "stream:json_t_for_time", "batch:latin1", "batch:--workers=-1",
            "garpos:obs_bare_cr", "gnatss:sv_swapped", "navigate:--dr-noise=1e-8"}
    chosen = [c for i, c in enumerate(cases) if not c.slow and (i % 6 == 0 or c.name in must)]
    assert must <= {c.name for c in chosen} and len(chosen) >= 80
    outcomes = [catalogue.run_case(c, limit=60) for c in chosen]
    bad = [(o.case.name, o.verdict, o.problems[:2]) for o in outcomes
           if o.verdict not in ("ok", "refused")]
    assert not bad
    verdicts = {o.verdict for o in outcomes}
    assert verdicts == {"ok", "refused"}
