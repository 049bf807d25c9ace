# pytest suite of the Python module `drape` (python/), run by ctest as Python.Bindings with
# PYTHONPATH at the built module, DRAPE_BIN the drape program and DRAPE_SOURCE_DIR the tree.
import os
import pathlib

import pytest


@pytest.fixture(scope="session")
def source_dir():
    return pathlib.Path(os.environ.get("DRAPE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


@pytest.fixture(scope="session")
def drape_bin():
    path = os.environ.get("DRAPE_BIN")
    if not path:
        pytest.fail("DRAPE_BIN is not set: run the suite through ctest (Python.Bindings)")
    return path
