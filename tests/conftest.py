import os

# One BLAS thread per test process (set before NumPy loads OpenBLAS; an explicit setting is
# kept). The suite runs one process per core (-n auto): OpenBLAS's own threads on top of
# them oversubscribe the cores, and its waiting threads spin: measured on 2 cores under load,
# tests/survey_in/test_measured_gain.py took 18.9 s of CPU with them and 4.5 s without.
# Subprocesses (the CLI runs, notebook kernels) inherit it.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import signal  # noqa: E402
import threading  # noqa: E402

import matplotlib  # noqa: E402
import pytest  # noqa: E402

matplotlib.use("Agg")


def pytest_configure(config):
    """Give the tests of Ctrl-C Python's SIGINT handler where the suite inherited it ignored.

    A suite started in the background by a shell (``pytest &``) inherits SIGINT ignored, and
    so would its subprocesses: the tests of Ctrl-C (a real SIGINT in-process, or sent to a
    command they start) then saw nothing happen. A terminal's Ctrl-C gives the handler.
    """
    if (threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.SIG_IGN):
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_addoption(parser):
    parser.addoption(
        "--with-docs-build", action="store_true", default=False,
        help="also run what CI's documentation build runs (.ci/run): execute every notebook "
             "and build the API pages (needs the docs extra for the latter)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--with-docs-build"):
        return
    skip = pytest.mark.skip(reason="run by the docs build in .ci/run (or pytest "
                                   "--with-docs-build)")
    for item in items:
        if "docs_build" in item.keywords:
            item.add_marker(skip)


@pytest.fixture()
def seagap_copy(tmp_path):
    """Return ``make(n_lines)``: the shipped SeaGap survey's first lines and its companions,
    copied into a folder of ``tmp_path`` (its ``obsdata.inp`` returned), to break."""
    import shutil

    from bayes_mpem.io.formats import sample_file

    def make(n_lines):
        folder = tmp_path / "seagap"
        folder.mkdir()
        for name in ("pxp-ini.inp", "tr-ant.inp", "ss_prof.inp"):
            shutil.copy(sample_file(f"seagap/{name}"), folder / name)
        lines = sample_file("seagap/obsdata.inp").read_text().splitlines(keepends=True)
        (folder / "obsdata.inp").write_text("".join(lines[:n_lines]))
        return folder / "obsdata.inp"

    return make
