"""The reading of GARPOS's results in ``benchmarks/gnssa_garpos.py`` (GARPOS itself is not run)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "gnssa_garpos.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("gnssa_garpos", PATH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _result(folder, cent_sigma=0.0, station_sigma=0.01, name="SIM.0000_L+00.0_g-03.0"):
    """A result in GARPOS's layout: the site file's keys with solved values, its comment lines
    (the model and the iterations, as GARPOS writes them), and -var.dat."""
    pos = np.array([[-500.0, 400.0, -1500.0], [600.0, 300.0, -1510.0], [50.0, -700.0, -1490.0]])
    lines = ["[Obs-parameter]", " Site_name   = SIM", "[Site-parameter]",
             " Stations    = M01 M02 M03", "[Model-parameter]"]
    lines += [f" M0{i + 1}_dPos    = {p[0]:.4f} {p[1]:.4f} {p[2]:.4f} {station_sigma} 0.01 0.01"
              " 0 0 0" for i, p in enumerate(pos)]
    lines.append(f" dCentPos    = 0.1000 -0.2000 0.0500 {cent_sigma} {cent_sigma} {cent_sigma}"
                 " 0 0 0")
    lines += ["#Inversion loop 001, RMS(TT) =   1.377558 ms, used_shot = 100.0%",
              "#Inversion loop 002, RMS(TT) =   0.035684 ms, used_shot = 100.0%",
              "#  ABIC =       17105.623472  misfit =  0.003 _T2.0",
              "# lambda_0^2 =   1.00000000", "# mu_t = 300.00000000 sec."]
    res = Path(folder) / f"{name}-res.dat"
    res.write_text("\n".join(lines) + "\n")
    gen = np.random.default_rng(0)
    a = gen.normal(size=(12, 12))  # 9 positions and 3 more parameters, correlated
    cov = 1e-4 * (a @ a.T)
    np.savetxt(str(res).replace("-res.dat", "-var.dat"), cov, delimiter=",")
    return res, pos, cov


def test_the_centre_is_the_mean_of_the_stations_with_their_covariance(bench, tmp_path):
    res, pos, cov = _result(tmp_path)
    out = bench.read_result(res)
    np.testing.assert_allclose(out["centre"], pos.mean(0) + [0.1, -0.2, 0.05])
    # the centre's variance: the 3 x 3 blocks of the 9 positions averaged, cross terms included
    want = [cov[np.ix_(range(c, 9, 3), range(c, 9, 3))].sum() / 9 for c in range(3)]
    np.testing.assert_allclose(out["sd"], np.sqrt(want))


def test_a_solved_array_shift_is_refused(bench, tmp_path):
    res, _, _ = _result(tmp_path, cent_sigma=1.0)
    with pytest.raises(RuntimeError, match="dCentPos was solved"):
        bench.read_result(res)


def test_the_model_comes_from_the_result_s_name_or_the_grid(bench, tmp_path):
    res, _, _ = _result(tmp_path, name="SIM.0000_L-01.0_T5.0")
    out = bench.read_result(res, ([-2.0, -1.0], [-3.0], [0.0, 5.0]))
    assert out["model"] == (-1.0, -3.0, 5.0)  # Lambda0 and mu_t named; gradLambda the grid's one
    assert out["abic"] == pytest.approx(17105.623472)
    assert out["loops"] == 2
    # a dimension searched but not named cannot be told
    assert bench.read_result(res, ([-1.0], [-3.0, -2.0], [5.0]))["model"] is None


def test_a_held_station_is_refused(bench, tmp_path):
    res, _, _ = _result(tmp_path, station_sigma=0.0)
    with pytest.raises(RuntimeError, match="sigma 0"):
        bench.read_result(res)


def test_the_seagap_survey_rewritten_for_garpos_is_located_where_seagap_s_own_is(bench, tmp_path):
    from bayes_mpem.io.formats import sample_file
    from bayes_mpem.io.garpos import read_garpos
    from bayes_mpem.io.seagap import read_seagap
    from bayes_mpem.survey_in.array import from_sphere
    from bayes_mpem.survey_in.array_survey import locate_array_survey
    from bayes_mpem.survey_in.survey import locate_survey

    site = bench.seagap_as_garpos(tmp_path)
    rewritten = locate_array_survey(read_garpos(site), correlation="off", gradients="off",
                                    position_prior="off").fits["array"]  # SeaGap has none
    own = locate_survey(read_seagap(sample_file("seagap/obsdata.inp")), speed_intervals=None,
                        correlation="off", gradients="off").fits["array"]
    # the smooth speed and no gradients, as the rewrite's fit above
    surface = -own.model["surface_depth"]  # the sea surface's height in SeaGap's frame
    e, n, u = from_sphere(*own.enu.T, own.model["earth_radius"])
    np.testing.assert_allclose(rewritten.enu, np.column_stack([e, n, u - surface]), atol=1e-4)
