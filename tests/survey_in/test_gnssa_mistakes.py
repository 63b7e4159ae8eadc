"""Mistakes real GNSS-A campaign files carry: each refused with where, or left out and named.

Found by an independent hunt for malformed inputs (session 46): each was a wrong answer at
exit 0 before.
"""

import warnings

import numpy as np
import pandas as pd
import pytest

from bayes_mpem.cli import main
from bayes_mpem.exceptions import InputError, LocateWarning
from bayes_mpem.io.formats import read_survey
from bayes_mpem.io.garpos import read_garpos, write_garpos
from bayes_mpem.survey_in.array_survey import isolated_shots, locate_array_survey
from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A half-hour GARPOS campaign as files, and its clean centre."""
    folder = tmp_path_factory.mktemp("garpos")
    sim = simulate_gnssa(hours=0.5, rng=11)
    site = write_garpos(folder, sim.pings, sim.header)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)
        centre = locate_array_survey(read_garpos(site)).fits["array"].centre()[0]
    return site, centre


def _copy(site, tmp_path):
    for f in site.parent.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    return tmp_path / site.name


def test_a_slipped_sign_in_a_prior_position_is_refused_naming_the_transponder(campaign,
                                                                                tmp_path,
                                                                                capsys):
    """M01's east given with the wrong sign (about 1 km off): the robust start cannot reach its
    replies, the EM called all of them spurious and the centre was hundreds of metres off."""
    site = _copy(campaign[0], tmp_path)
    lines = site.read_text().splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if line.lstrip().startswith("M01_dPos"))
    key, values = lines[i].split("=")
    east, rest = values.split(maxsplit=1)
    lines[i] = f"{key}= {-float(east):.4f} {rest}"
    site.write_text("".join(lines))
    with pytest.raises(InputError, match=r"transponder M01: \d+ of its \d+ replies called "
                                         r"spurious.*prior position"):
        locate_array_survey(read_garpos(site))
    out = tmp_path / "out"
    assert main(["locate", str(site), "--out", str(out)]) == 2
    assert "M01" in capsys.readouterr().err and not (out / "summary.json").exists()


def test_a_few_replies_all_spurious_are_refused_too(tmp_path):
    """Six replies of M01, its prior east's sign slipped: all six were called spurious, under
    the share check's ten replies, and the centre was 259 m off at exit 0."""
    sim = simulate_gnssa(hours=0.5, rng=11)
    m01 = np.flatnonzero(sim.pings["transponder"].to_numpy() == "M01")
    pings = sim.pings.drop(index=sim.pings.index[m01[6:]]).reset_index(drop=True)
    header = dict(sim.header, transponders=sim.header["transponders"].copy())
    header["transponders"].loc["M01", "east"] *= -1
    site = write_garpos(tmp_path, pings, header)
    with pytest.raises(InputError, match=r"transponder M01: 6 of its 6 replies called spurious"):
        locate_array_survey(read_garpos(site))
    header["transponders"].loc["M01", "east"] *= -1  # the right prior: its six replies fit
    (tmp_path / "right").mkdir()
    site = write_garpos(tmp_path / "right", pings, header)
    fit = locate_array_survey(read_garpos(site)).fits["array"]
    assert fit.n_spurious(0) < 6 and np.all(np.abs(fit.centre()[0][:2]) < 1.0)


def test_a_shot_whose_time_slipped_hours_is_left_out_and_named(campaign, tmp_path):
    """One ``ST`` (and ``RT``) ten hours early: it was called true (its own sound speed fits
    it), the campaign's span grew to 10.5 h and the centre moved 4-7 cm."""
    site = _copy(campaign[0], tmp_path)
    obs = next(tmp_path.glob("*-obs.csv"))
    head, table = obs.read_text().split("\n", 1)
    rows = pd.read_csv(pd.io.common.StringIO(table), index_col=0)
    rows.loc[rows.index[100], ["ST", "RT"]] -= 36000.0
    obs.write_text(head + "\n" + rows.to_csv())
    with pytest.warns(LocateWarning, match="isolated in time"):
        res = locate_array_survey(read_garpos(site))
    centre = res.fits["array"].centre()[0]
    assert np.abs(centre - campaign[1]).max() < 0.005  # as without the shot (1 mm here)
    cls = res.classified
    left = cls[cls["reason"].astype(str).str.startswith("isolated in time")]
    assert len(left) == 1 and res.summary["not_fitted"]["isolated_in_time"] == 1
    assert res.summary["gradients"]["choice"] == "auto" and not res.summary["gradients"][
        "fitted"]  # judged on the half hour, not on a 10.5-h span


def test_two_sessions_apart_are_not_isolated_and_a_stray_group_is():
    t = np.r_[np.arange(0.0, 3600.0, 20.0), 30000.0 + np.arange(0.0, 1800.0, 20.0)]
    assert not isolated_shots(pd.DataFrame({"time": t}))[0].any()
    t2 = np.r_[t, 80000.0, 80010.0]
    mask, why = isolated_shots(pd.DataFrame({"time": t2}))
    assert mask.nonzero()[0].tolist() == [t.size, t.size + 1]
    assert why[-1].startswith("isolated in time: 2 shots 13.4 h from every other")
    t3 = np.r_[t, 80000.0, 80010.0, -20000.0]  # two groups: each its own reason
    mask, why = isolated_shots(pd.DataFrame({"time": t3}))
    assert mask.sum() == 3 and len(set(why[mask])) == 2


def _atd(site, change):
    """Rewrite the site file's ``ATDoffset`` values by ``change(parts)``; return its index."""
    lines = site.read_text().splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if line.lstrip().startswith("ATDoffset"))
    key, values = lines[i].split("=")
    lines[i] = f"{key}= {' '.join(change(values.split()))}\n"
    site.write_text("".join(lines))
    return i


def test_atd_offset_sigmas_above_zero_are_said_to_be_held(campaign, tmp_path):
    """GARPOS estimates the antenna-transducer offset where its sigmas are above 0; locate
    holds it as given, which it now says (the sigmas were read and dropped in silence)."""
    site = _copy(campaign[0], tmp_path)
    _atd(site, lambda parts: parts[:3] + ["0.5", "0.5", "0.5"] + parts[6:])
    with pytest.warns(LocateWarning, match=r"ATDoffset sigmas 0.5, 0.5, 0.5: GARPOS estimates "
                                           r"the offset .* locate holds it"):
        res = locate_array_survey(read_garpos(site))
    np.testing.assert_allclose(res.fits["array"].centre()[0], campaign[1], atol=1e-9)


def test_intervals_that_cannot_be_computed_are_refused_not_printed_as_nan():
    """Every weight of the grid not positive definite: the record's evidences are None (a
    bare numpy warning reached the user) and the fit is refused (intervals printed NaN)."""
    from types import SimpleNamespace

    from bayes_mpem.survey_in.array import _relative
    from bayes_mpem.survey_in.array_survey import _check_intervals

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _relative(np.array([-np.inf, -np.inf])) == [None, None]
    assert _relative(np.array([-1.0, 2.0])) == [-3.0, 0.0]
    fit = SimpleNamespace(ids=("A", "B"), sd=np.array([[0.1, 0.1, 0.2], [np.nan, 0.1, 0.2]]))
    with pytest.raises(InputError, match=r"x.ini: the intervals of B could not be computed"):
        _check_intervals(SimpleNamespace(source="x.ini"), fit)


@pytest.fixture()
def seagap(seagap_copy):
    """The shipped SeaGap survey's first 600 lines with its companion files."""
    return seagap_copy(600)


def test_one_at_a_time_with_a_fitted_tat_prints_its_interval(seagap, tmp_path, capsys):
    """``--one-at-a-time --fit-tat`` ended in "internal error: KeyError: 'interval'"."""
    assert main(["locate", str(seagap), "--one-at-a-time", "--fit-tat", "--out",
                 str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "TAT" in out and "(fixed)" not in out.split("TAT", 1)[1].splitlines()[0]


def test_swapped_prior_positions_are_refused(seagap, tmp_path):
    """SeaGap's pxp-ini.inp with its first two lines swapped: the two transponders moved
    1,956 m and, through the gradients' deep term (on the priors), the centre by up to 11 cm
    with the same shots, at exit 0."""
    pxp = seagap.with_name("pxp-ini.inp")
    lines = pxp.read_text().splitlines(keepends=True)
    lines[0], lines[1] = lines[1], lines[0]
    pxp.write_text("".join(lines))
    with pytest.raises(InputError, match=r"pxp-ini.inp: transponder \d was located [\d,]+ m "
                                         r"from its prior position .* more than 0.2 of its "
                                         r"depth"):
        locate_array_survey(read_survey(seagap))


def test_more_coefficients_than_the_replies_carry_are_refused_at_once(campaign, tmp_path):
    """A half-hour campaign with 50 unpenalised intervals and the gradients ran past 7 min;
    SeaGap with knots every 0.1 min past 5 min. Refused before the fit, with a size that
    runs."""
    import time

    from bayes_mpem.survey_in.array import _check_size

    raw = read_garpos(campaign[0])
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=r"speed_intervals \(--speed-intervals\) 50: 277 "
                                         r"parameters for \d+ replies, unpenalised; .* give [23]\d "
                                         r"intervals or fewer, or leave the gradients out"):
        locate_array_survey(raw, speed_intervals=50, gradients="on")
    assert time.perf_counter() - t0 < 20.0
    with pytest.raises(InputError, match=r"knot_minutes \(--knot-minutes\) 0.1: 4,412 parameters "
                                         r"for 3,347 replies; .* give knots every 1.4 min"):
        _check_size(3347, 12, 880, 5, True, 877, 0.1, (0.0, 52560.0))  # 1.3 min was refused
    _check_size(3347, 12, 580, 5, True, 577, 1.5, (0.0, 52560.0))  # over one a reply, under 3,000
    _check_size(3347, 12, 178, 5, True, 175, 5.0, (0.0, 52560.0))  # SeaGap's defaults: fine
    _check_size(353, 12, 182, 1, False, 179, 5.0, (0.0, 1800.0))  # no gradients: one a reply
    with pytest.raises(InputError, match="expected at most one a reply: give 338 intervals"):
        _check_size(353, 12, 400, 1, False, 397, 5.0, (0.0, 1800.0))


def test_a_turn_around_time_longer_than_the_travel_times_is_refused(seagap, tmp_path,
                                                                     capsys):
    """``--tat 10`` (seconds for milliseconds): every ping spurious, a depth of -15 m with an
    interval of 1e8 m, at exit 0."""
    assert main(["locate", str(seagap), "--one-at-a-time", "--tat", "10", "--out",
                 str(tmp_path / "o")]) == 2
    assert "tat (--tat) 10 s: not shorter than the median two-way travel time" in (
        capsys.readouterr().err)


def test_a_correlation_time_below_a_second_is_refused_naming_the_option():
    """``--correlation 5e-324`` passed the parser and failed in the whitener with NumPy's
    "array must not contain infs or NaNs; give a shorter time" (backwards advice)."""
    import argparse

    from bayes_mpem.cli.options import correlation
    from bayes_mpem.survey_in.array import correlation_spec

    with pytest.raises(argparse.ArgumentTypeError, match=r"MU_T seconds, 0 or in \[1, 1200\]"):
        correlation("5e-324")
    with pytest.raises(InputError, match="mu_t 0 or at least 1 s"):
        correlation_spec((1e-300,))
    assert correlation("0") == (0.0, 0.5, 0.0) and correlation_spec((1.0,))[0] == 1.0


def test_a_companion_that_is_a_folder_is_named_as_that_companion(seagap):
    """A folder named ss_prof.inp was reported as "survey file ... is a folder"."""
    prof = seagap.with_name("ss_prof.inp")
    prof.unlink()
    prof.mkdir()
    with pytest.raises(InputError, match=r"ss_prof.inp: is a folder; expected SeaGap's "
                                         r"ss_prof.inp file"):
        read_survey(seagap)


def test_an_atd_offset_upward_is_refused_naming_the_line(campaign, tmp_path):
    """A hunt (session 48): ATDoffset downward typed -12 for 12 put the transducer 22 m above
    the sea and every transponder 24 m too shallow at 0.2 m sds, at exit 0; 0 (positions
    already the transducer's) stays allowed."""
    site = _copy(campaign[0], tmp_path)
    i = _atd(site, lambda parts: parts[:2] + ["-" + parts[2]] + parts[3:])
    with pytest.raises(InputError, match=rf"line {i + 1} \(ATDoffset\): ATDoffset downward: "
                                         r"expected a number in \[0, 100\], got '-12.*the "
                                         r"transducer is under the water"):
        read_garpos(site)
    _atd(site, lambda parts: parts[:2] + ["150"] + parts[3:])  # out of range, no sign slip
    with pytest.raises(InputError, match=r"got '150'$"):
        read_garpos(site)
    _atd(site, lambda parts: parts[:2] + ["0.0"] + parts[3:])
    assert read_garpos(site).header["atd_offset"][2] == 0.0


def _swap_labels(site, share):
    """Swap M01's and M02's labels in the last ``share`` of the shots file's lines."""
    obs = next(site.parent.glob("*obs.csv"))
    head, *rows = obs.read_text().splitlines(keepends=True)
    columns = rows[0].strip().split(",")
    mt = columns.index("MT")
    first = int(len(rows[1:]) * (1 - share))
    for i in range(1 + first, len(rows)):
        cells = rows[i].rstrip("\n").split(",")
        cells[mt] = {"M01": "M02", "M02": "M01"}.get(cells[mt], cells[mt])
        rows[i] = ",".join(cells) + "\n"
    obs.write_text(head + "".join(rows))


@pytest.mark.parametrize("share", [0.7, 0.15])
def test_labels_swapped_part_of_the_way_are_refused_naming_the_lines(campaign, tmp_path, share):
    """A hunt (session 48): M01's and M02's labels swapped for the last 70 % of the shots
    (a deck unit re-cabled): 29 % of their replies true, above the share refused, so M02 came
    out 29 m off at sds under 1 m and the centre 5 m off, at exit 0 with no warning."""
    site = _copy(campaign[0], tmp_path)
    _swap_labels(site, share)
    with pytest.raises(InputError, match=r"obs.csv: \d+ of the \d+ replies labelled M0[12] "
                                         r"\(lines \d+ to \d+\) arrive when M0[12]'s would at "
                                         r"the same transmit time"):
        locate_array_survey(read_garpos(site))


def test_a_transponder_mostly_spurious_is_warned_of(campaign, tmp_path):
    """Replies that are no transponder's (another array's, concatenated): more than half of
    one transponder's called spurious is said, where no other transponder explains them."""
    site = _copy(campaign[0], tmp_path)
    obs = next(site.parent.glob("*obs.csv"))
    head, *rows = obs.read_text().splitlines(keepends=True)
    columns = rows[0].strip().split(",")
    mt, tt, rt = columns.index("MT"), columns.index("TT"), columns.index("RT")
    gen = np.random.default_rng(0)
    for i in range(1, len(rows)):
        cells = rows[i].rstrip("\n").split(",")
        if cells[mt] == "M03" and gen.random() < 0.7:
            late = gen.uniform(0.3, 1.5)
            cells[tt] = f"{float(cells[tt]) + late:.7f}"
            cells[rt] = f"{float(cells[rt]) + late:.6f}"
        rows[i] = ",".join(cells) + "\n"
    obs.write_text(head + "".join(rows))
    with pytest.warns(LocateWarning, match=r"transponder M03: \d+ of its \d+ replies called "
                                           r"spurious \(more than 50 %\)"):
        locate_array_survey(read_garpos(site))


@pytest.mark.parametrize("ci", [95, 1.0, 0.0, -0.5, float("nan"), "x", None])
def test_locate_survey_refuses_a_ci_outside_0_1(campaign, ci):
    """``ci=95``, NaN, 1, 0 or -0.5 gave NaN, infinite, zero-width or inverted intervals and
    a "9500 % region" in solution.txt; now refused by the check ``sample`` uses."""
    from bayes_mpem.survey_in.survey import locate_survey

    with pytest.raises(InputError, match=r"^ci: expected a probability in \(0, 1\), got "):
        locate_survey(read_garpos(campaign[0]), ci=ci)


@pytest.mark.parametrize("knots", [1e-9, 0.001, 0.0999, 1441.0, float("inf"), float("nan")])
def test_locate_survey_refuses_a_knot_spacing_the_command_line_refuses(campaign, knots):
    """``knot_minutes=1e-9`` asked 445 GiB; 0.001 ran: both under ``--knot-minutes``' 0.1."""
    from bayes_mpem.survey_in.survey import locate_survey

    with pytest.raises(InputError, match=r"^knot_minutes: expected a number in \[0.1, 1440.0\], "
                                         r"got .* only costs memory"):
        locate_survey(read_garpos(campaign[0]), knot_minutes=knots)


def test_locate_survey_given_a_path_says_to_read_it_first(campaign):
    from bayes_mpem.survey_in.survey import locate_survey

    for given in (campaign[0], str(campaign[0])):
        with pytest.raises(InputError, match=r"^raw: expected a RawSurvey \(what .*read_survey "
                                             r"returns\), got the path .*read_survey\(path\)"):
            locate_survey(given)
    with pytest.raises(InputError, match="got a DataFrame$"):
        locate_survey(pd.DataFrame())


@pytest.mark.parametrize("option", [{"gradients": "on"}, {"knot_minutes": 2.5},
                                    {"flags": "reclassify"}, {"position_prior": "off"}])
def test_locate_survey_refuses_array_options_for_one_transponder(option):
    """The command line refused them; ``locate_survey`` read them and dropped them."""
    from bayes_mpem.io.formats import sample_file
    from bayes_mpem.survey_in.survey import locate_survey

    raw = read_survey(sample_file("obsrange/SIO_CC03.txt"))
    [(name, value)] = option.items()
    with pytest.raises(InputError, match=rf"^{name}={value!r}: for array surveys only"):
        locate_survey(raw, **option)


def test_replies_near_another_transponders_whose_own_are_true_are_no_swap(campaign, tmp_path):
    """A review: M02 placed 10-30 m from M01 and a quarter of M01's replies late by 1-10 ms
    (multipath) was refused as labels swapped. A swap takes B's own reply away; here M02's
    own replies at those shots stay true, so they are M01's late arrivals, not M02's."""
    site = _copy(campaign[0], tmp_path)
    obs = next(site.parent.glob("*obs.csv"))
    head, *rows = obs.read_text().splitlines(keepends=True)
    columns = rows[0].strip().split(",")
    mt, tt, rt, st = (columns.index(c) for c in ("MT", "TT", "RT", "ST"))
    cells = [r.rstrip("\n").split(",") for r in rows[1:]]
    m02 = {c[st]: float(c[tt]) for c in cells if c[mt] == "M02"}
    gen = np.random.default_rng(1)
    for c in cells:
        if c[mt] == "M01" and c[st] in m02 and gen.random() < 0.3:
            late = m02[c[st]] + 1e-3 - float(c[tt])  # where M02's would arrive, 1 ms later
            c[tt] = f"{float(c[tt]) + late:.7f}"
            c[rt] = f"{float(c[rt]) + late:.6f}"
    obs.write_text(head + rows[0] + "".join(",".join(c) + "\n" for c in cells))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)
        res = locate_array_survey(read_garpos(site))  # not refused
    assert res.summary["transponders"]["M01"]["n_spurious"] > 10
