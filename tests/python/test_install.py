"""cmake --install puts the module where the system interpreter looks for modules under the
install prefix, and the installed module works."""
import os
import pathlib
import subprocess
import sys

import pytest


def test_installed_module_lands_on_the_interpreters_path_and_imports(tmp_path):
    build, prefix, rel = (os.environ.get(k) for k in ("DRAPE_BUILD_DIR", "DRAPE_INSTALL_PREFIX", "DRAPE_PYTHON_INSTALL_DIR"))
    if not (build and prefix and rel):
        pytest.skip("run through ctest (Python.Bindings), which names the build")
    target = pathlib.Path(prefix) / rel
    if prefix == "/usr/local":  # the default prefix: the system interpreter must search there
        searched = subprocess.run([sys.executable, "-c", "import sys; print('\\n'.join(sys.path))"],
                                  capture_output=True, text=True, check=True).stdout.split("\n")
        assert str(target) in searched, (target, searched)
    # install the whole build into a staging root and import the module from there
    env = dict(os.environ, DESTDIR=str(tmp_path))
    subprocess.run(["cmake", "--install", build], env=env, check=True, capture_output=True)
    staged = tmp_path / target.relative_to("/")
    modules = list(staged.glob("drape*.so"))
    assert len(modules) == 1, list(staged.iterdir()) if staged.exists() else staged
    out = subprocess.run([sys.executable, "-c", "import drape, sys; w = drape.World(threads=1); "
                          "s = w.add_sheet(m=2, n=2); w.step(3); print(drape.__file__, w.step_count)"],
                         env=dict(os.environ, PYTHONPATH=str(staged)), capture_output=True, text=True, check=True)
    assert out.stdout.startswith(str(staged)) and out.stdout.split()[1] == "3"
