"""Warnings that help (issue 27 item 7): each names its fit; clean data send no one to diagnose."""

import json
import warnings

import pytest

import bayes_mpem as bm
from bayes_mpem.cli.parser import main
from bayes_mpem.exceptions import ModelCheckWarning
from bayes_mpem.lbl.survey.model_checks import PAPER_ADVICE, checks_record, plane_check


def test_the_demo_on_clean_data_suggests_no_diagnose_and_lists_its_warnings(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--no-bayes"]) == 0
    err = capsys.readouterr().err
    shown = [line for line in err.splitlines() if "Warning: " in line]
    assert shown  # the paper's EM misses the plane on beacons 1 and 2 (docs/paper-em.md)
    assert "diagnose" not in err and "late spurious replies" not in err
    assert " given" not in err  # the demo fixes sigma_DP, the user gave none
    for line in shown:
        assert "(the paper's EM)" in line or "(the mixture EM" in line, line
    md = (tmp_path / "summary.md").read_text()
    listed = md.split("## Warnings\n\n")[1].split("\n\n")[0].splitlines()
    assert [item[2:] for item in listed] == [" ".join(line.split()) for line in shown]


def test_the_paper_ems_checks_leave_out_what_its_probabilities_cannot_test(tmp_path):
    sim = bm.simulate_survey("abe58", rng=0, n_cycles=300)
    with warnings.catch_warnings(record=True):  # the paper's EM may flag its fit
        warnings.simplefilter("always")
        res = bm.fit(sim.survey, method="paper", sigma_dp=sim.truth["1"]["sigma_dp"], rng=0)
    names = {c["name"] for ch in res.checks.values() for c in ch}
    assert "outliers_before_direct" not in names and "direct_path_scatter" not in names
    assert {"direct_path_offset", "plane_off_surface"} <= names
    doc = json.loads(res.write(tmp_path)["summary"].read_text())
    for rec in (b["model_checks"] for b in doc["beacons"].values()):
        assert not rec["flags"] or rec["flags"][-1] == PAPER_ADVICE


def test_the_mixture_ems_warning_names_it_and_keeps_the_diagnose_advice():
    sim = bm.simulate_survey("abe58", rng=2, n_cycles=300, effects={"range_bias": 4.0})
    with pytest.warns(ModelCheckWarning, match=r"\(the mixture EM\).*bayes-mpem diagnose"):
        res = bm.fit(sim.survey, rng=0)
    assert all("outliers_before_direct" in {c["name"] for c in ch}
               for ch in res.checks.values())  # the mixture EM keeps every check


def test_the_advice_follows_the_fit():
    flags = plane_check(25.0)
    assert "diagnose" in checks_record(flags)["flags"][-1]
    assert "diagnose" in checks_record(flags, "posterior")["flags"][-1]
    assert checks_record(flags, "paper")["flags"][-1] == PAPER_ADVICE

