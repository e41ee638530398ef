"""What ships to pip users: the license, ``py.typed``, the type stubs of
``safenav._core``, and one Debian package list for bootstrap.sh and the README."""

from __future__ import annotations

import ast
import inspect
import re
import subprocess
import sys
from pathlib import Path

import safenav
from safenav import _core

ROOT = Path(__file__).resolve().parents[1]


def _debian_packages() -> list[str]:
    lines = (ROOT / "scripts" / "debian-packages.txt").read_text().splitlines()
    return [name for line in lines if (name := line.split("#")[0].strip())]


def test_bootstrap_installs_the_debian_package_list():
    line = next(row for row in (ROOT / "scripts" / "bootstrap.sh").read_text().splitlines()
                if row.startswith("mapfile -t DEB_PACKAGES"))
    out = subprocess.run(["bash", "-c", line + '\nprintf "%s\\n" "${DEB_PACKAGES[@]}"'], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    assert out.split() == _debian_packages()


def test_readme_quotes_the_debian_package_list():
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## pip install", 1)[1].split("\n## ", 1)[0]
    (command,) = re.findall(r"^apt-get install .*$", section, re.MULTILINE)
    assert command.split()[2:] == _debian_packages()


def test_wheel_metadata_carries_the_mit_license(tmp_path):
    # The build backend's metadata hook: no compiler involved.
    script = "import sys; from scikit_build_core.build import prepare_metadata_for_build_wheel as m; m(sys.argv[1])"
    subprocess.run([sys.executable, "-c", script, str(tmp_path)], cwd=ROOT, capture_output=True, check=True)
    (dist_info,) = tmp_path.glob("safenav-*.dist-info")
    assert "License-Expression: MIT" in (dist_info / "METADATA").read_text().splitlines()
    license_text = (dist_info / "licenses" / "LICENSE").read_text()
    assert license_text.startswith("MIT License") and "Copyright (c) 2026 the safenav authors" in license_text


def test_package_is_marked_typed():
    # PEP 561: the marker sits in the package, which ships whole (wheel.packages).
    assert (Path(safenav.__file__).parent / "py.typed").is_file()


def _stub() -> ast.Module:
    stub = Path(_core.__file__).resolve().with_name("_core.pyi")
    assert stub.is_file(), f"{stub} missing: the build did not run pybind11-stubgen"
    return ast.parse(stub.read_text())


def _defined(body) -> set[str]:
    names = set()
    for node in body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign):
            names.add(node.target.id)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def test_core_stub_declares_every_public_name():
    tree = _stub()
    public = {n for n in dir(_core) if not n.startswith("_") and not inspect.ismodule(getattr(_core, n))}
    assert public <= _defined(tree.body), sorted(public - _defined(tree.body))
    classes = {node.name: node for node in tree.body if isinstance(node, ast.ClassDef)}
    checked = 0
    for name in public:
        obj = getattr(_core, name)
        if inspect.isclass(obj):
            members = {m for m in vars(obj) if not m.startswith("_")}
            assert members <= _defined(classes[name].body), (name, sorted(members - _defined(classes[name].body)))
            checked += len(members)
    assert checked > 50


def test_core_stub_is_fully_annotated():
    functions = [node for node in ast.walk(_stub()) if isinstance(node, ast.FunctionDef)]
    assert len(functions) > 50
    for fn in functions:
        params = fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs
        unannotated = [a.arg for a in params if a.annotation is None and a.arg not in ("self", "cls")]
        assert not unannotated and fn.returns is not None, (fn.name, fn.lineno, unannotated)
