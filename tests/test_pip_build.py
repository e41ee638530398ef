"""`pip install .` and `pip wheel .` as a new user runs them: pip's isolated
build (build requirements from PyPI, not from our .venv), in a fresh virtual
environment, from a copy of the checkout.  Slow without ccache (it compiles
the core twice); with ccache, which bootstrap.sh installs and CMakeLists.txt
uses, both builds take the editable build's objects.  It is the only check
that the README's plain pip path works: the editable build in .venv runs without
isolation, where pybind11-stubgen and numpy are always importable."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(cmd, **kw):
    out = subprocess.run(cmd, capture_output=True, text=True, **kw)
    assert out.returncode == 0, f"{' '.join(map(str, cmd))} failed ({out.returncode}):\n{out.stdout[-4000:]}\n{out.stderr[-4000:]}"
    return out


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """A copy of the checkout (tracked and untracked, not ignored files, as a
    clone would have them), a fresh venv with pip, and the build environment."""
    base = tmp_path_factory.mktemp("pip")
    src = base / "src"
    files = _run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT).stdout
    for rel in filter(None, files.split("\0")):
        if (ROOT / rel).is_file():
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / rel, src / rel)
    venv.create(base / "venv", with_pip=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PIP_NO_BUILD_ISOLATION")}
    return base, src, base / "venv" / "bin" / "python", env


def test_pip_wheel_builds_a_complete_wheel(fresh):
    base, src, python, env = fresh
    _run([python, "-m", "pip", "wheel", "--no-deps", "-q", "-w", base / "dist", src], env=env)
    (wheel,) = (base / "dist").glob("safenav-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert any(n.startswith("safenav/_core.") and n.endswith(".so") for n in names), names
    assert "safenav/_core.pyi" in names and "safenav/py.typed" in names
    assert "safenav/data/default_scenario.toml" in names


def test_pip_install_in_a_fresh_venv_imports_and_runs(fresh):
    base, src, python, env = fresh
    _run([python, "-m", "pip", "install", "-q", src], env=env)
    script = ("import safenav, numpy as np; from safenav import _core; "
              "assert 'site-packages' in safenav.__file__, safenav.__file__; "
              "m = _core.MeasurementModel.range(np.array([[3.0, 4.0]]), 0.1); "
              "print(m.predict(np.zeros(4))[0])")
    out = _run([python, "-c", script], env=env, cwd=base)
    assert float(out.stdout.strip()) == 5.0
