"""Issue 13's layout rules, read from the source: no module reaches into
another module's private names, and angles are wrapped by the core's
``wrap_angle`` only."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "safenav"
def _modules():
    return sorted(PACKAGE.rglob("*.py"))


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__") and name != "_core"


def private_uses(source: str) -> list[str]:
    """Private names of other safenav modules that ``source`` uses: ``from .m
    import _x``, ``m._x`` for a module ``m`` imported from the package, and
    ``getattr(obj, "_x", ...)``."""
    tree = ast.parse(source)
    modules, found = set(), []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("safenav")):
            for a in node.names:
                if _private(a.name):
                    found.append(f"from {'.' * node.level}{node.module or ''} import {a.name}")
                else:
                    modules.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            modules.update((a.asname or a.name).split(".")[0] for a in node.names if a.name.startswith("safenav"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules \
                and _private(node.attr):
            found.append(f"{node.value.id}.{node.attr}")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr" \
                and len(node.args) > 1 and isinstance(node.args[1], ast.Constant) \
                and isinstance(node.args[1].value, str) and _private(node.args[1].value):
            found.append(f"getattr(..., {node.args[1].value!r})")
    return found


def test_the_checker_finds_each_kind_of_private_use():
    src = ("from .detect import _check_image\nfrom . import cli\nimport safenav.world\n"
           "cli._run_folder()\nsafenav._checks\ngetattr(s, '_s', s)\nfrom ._checks import as_array\n"
           "from . import _core\nself._x\nobj.__class__\n")
    assert sorted(private_uses(src)) == ["cli._run_folder", "from .detect import _check_image",
                                         "getattr(..., '_s')", "safenav._checks"]


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_uses_another_modules_private_names(path):
    assert private_uses(path.read_text()) == []


ADHOC_WRAPS = (re.compile(r"%\s*\(\s*2\s*\*\s*(np|math)\.pi\s*\)"), re.compile(r"np\.angle\(\s*np\.exp\(\s*1j"),
               re.compile(r"atan2\(\s*(np|math)\.sin\(([^()]*)\)\s*,\s*(np|math)\.cos\(\2\)\s*\)"))


@pytest.mark.parametrize("folder", ["placement", "vision"])
def test_angles_are_wrapped_by_the_cores_wrap_angle(folder):
    for path in sorted((PACKAGE / folder).rglob("*.py")):
        text = path.read_text()
        assert not [p.pattern for p in ADHOC_WRAPS if p.search(text)], path.name


@pytest.mark.parametrize("text", ["(b + np.pi) % (2 * np.pi) - np.pi", "np.angle(np.exp(1j * e[:, 2]))",
                                  "math.atan2(math.sin(err), math.cos(err))"])
def test_the_wrap_patterns_match_the_three_adhoc_forms(text):
    assert any(p.search(text) for p in ADHOC_WRAPS)
    assert not any(p.search("math.atan2(np.sin(res).mean(), np.cos(res).mean())") for p in ADHOC_WRAPS)
