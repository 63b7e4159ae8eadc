import matplotlib
import pytest

matplotlib.use("Agg")


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
