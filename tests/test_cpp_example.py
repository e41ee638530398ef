"""The C++ core installs as a CMake package and a separate project embeds it.

Installs the shared ``safenav::core`` to a temporary prefix, then configures
``cpp/examples`` as its own CMake project with ``find_package(safenav)``,
builds ``vehicle_loop`` and runs it.  The consumer must link ``safenav::core``
alone: the exported link interface names imported targets (Eigen's), not the
absolute paths of OMPL, ODE, GMP, MPFR or OpenCV, and the consumer configures
with CGAL, OMPL, OpenCV and Boost hidden from CMake.

The core is installed from the build that produced the imported
``safenav._core`` when there is one (it holds the compiled objects already),
else from a standalone build under ``build/`` that reruns incrementally.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from safenav import _core

ROOT = Path(__file__).resolve().parents[1]
CMAKE = shutil.which("cmake")
GEN = ["-G", "Ninja"] if shutil.which("ninja") else []
# Libraries private to the shared core: no consumer may name them.
PRIVATE_LIBS = re.compile(r"ompl|opencv|gmp|mpfr|boost|cgal|libode|^-lode$", re.IGNORECASE)
HIDDEN = ["-DCMAKE_DISABLE_FIND_PACKAGE_" + pkg + "=ON" for pkg in ("CGAL", "ompl", "OpenCV", "Boost")]


def _run(*cmd, cwd=ROOT):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


def _module_build_dir() -> Path | None:
    """The CMake build of this tree that the imported ``safenav._core`` came from, if any."""
    for folder in Path(_core.__file__).resolve().parents:
        cache = folder / "CMakeCache.txt"
        if cache.is_file():
            home = re.search(r"^CMAKE_HOME_DIRECTORY:INTERNAL=(.*)$", cache.read_text(), re.MULTILINE)
            return folder if home and Path(home.group(1)).resolve() == ROOT else None
    return None


@pytest.fixture(scope="module")
def installed_prefix(tmp_path_factory):
    assert CMAKE, "cmake is required (pip install cmake, or apt-get install cmake)"
    build = _module_build_dir()
    if build is None:
        build = ROOT / "build" / "cpp-package-test" / "core"
        _run(CMAKE, "-S", str(ROOT), "-B", str(build), *GEN, "-DCMAKE_BUILD_TYPE=Release",
             "-DSAFENAV_BUILD_PYTHON=OFF")
    _run(CMAKE, "--build", str(build), "--target", "safenav_core", "--parallel", "2")
    prefix = tmp_path_factory.mktemp("prefix")
    _run(CMAKE, "--install", str(build), "--component", "cpp", "--prefix", str(prefix))
    return prefix


@pytest.fixture(scope="module")
def example_build(installed_prefix, tmp_path_factory):
    build = tmp_path_factory.mktemp("example")
    _run(CMAKE, "-S", str(ROOT / "cpp" / "examples"), "-B", str(build), *GEN, "-DCMAKE_BUILD_TYPE=Release",
         f"-DCMAKE_PREFIX_PATH={installed_prefix}", *HIDDEN)
    _run(CMAKE, "--build", str(build))
    return build


def _link_command(build: Path) -> str:
    if GEN:
        return _run("ninja", "-C", str(build), "-t", "commands", "vehicle_loop").strip().splitlines()[-1]
    return (build / "CMakeFiles" / "vehicle_loop.dir" / "link.txt").read_text()


def test_installed_package_layout(installed_prefix):
    assert (installed_prefix / "include" / "safenav" / "filters.hpp").is_file()
    configs = list(installed_prefix.glob("lib*/cmake/safenav/safenavConfig.cmake"))
    assert configs, "safenavConfig.cmake was not installed"
    # The core ships as a shared library, not as a static archive.
    assert list(installed_prefix.glob("lib*/libsafenav_core.so*"))
    assert not list(installed_prefix.glob("lib*/*.a"))
    # Public headers expose only Eigen and the standard library.
    for header in (installed_prefix / "include" / "safenav").glob("*.hpp"):
        for line in header.read_text().splitlines():
            if line.startswith("#include <"):
                name = line.split("<")[1].split(">")[0]
                # Eigen, or a standard header (no directory, no extension).
                assert name.split("/")[0] == "Eigen" or ("/" not in name and "." not in name), (header, line)


def test_exported_link_interface_names_targets_not_paths(installed_prefix):
    (targets,) = installed_prefix.glob("lib*/cmake/safenav/safenavTargets.cmake")
    text = "".join(p.read_text() for p in targets.parent.glob("safenavTargets*.cmake"))
    interface = re.findall(r'INTERFACE_LINK_LIBRARIES "([^"]*)"', text)
    assert interface == ["Eigen3::Eigen"], interface
    # No absolute path (our own library is found relative to the prefix), and
    # no library file but ours.
    code = re.sub(r"#.*", "", text)
    assert not re.findall(r'(?:^|[\s";:])(/[^\s";>]+)', code, re.MULTILINE)
    libraries = re.findall(r"[\w.+-]+\.(?:so|a)\b[\w.]*", code)
    assert libraries and all(lib.startswith("libsafenav_core.so") for lib in libraries), libraries
    # The package config looks for Eigen only.
    config = re.sub(r"#.*", "", (targets.parent / "safenavConfig.cmake").read_text())
    assert not PRIVATE_LIBS.search(config), config


def test_consumer_links_only_safenav_core(example_build):
    link = _link_command(example_build).split()
    assert any("libsafenav_core.so" in tok for tok in link), link
    assert not [tok for tok in link if PRIVATE_LIBS.search(Path(tok).name)], link


def test_example_builds_against_installed_package_and_runs(example_build):
    exe = example_build / "vehicle_loop"
    out = _run(str(exe), "400")
    fields = dict(kv.split("=", 1) for kv in out.split() if "=" in kv)
    assert int(fields["steps"]) == 400
    assert int(fields["fixes"]) >= 70          # 80 fixes offered; the 99.9% gate rejects few
    assert float(fields["error"].rstrip("m")) < 0.2
    # A bad argument is reported, not a crash.
    bad = subprocess.run([str(exe), "0"], capture_output=True, text=True)
    assert bad.returncode == 2 and "steps must be > 0" in bad.stderr
