"""The package's layout rules, read from the source: no module reaches into
another module's private names, angles are wrapped by the core's
``wrap_angle`` only, no library file is longer than 600 lines, and the
modules import each other without a cycle."""

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


# --------------------------------------------------------------------------- file size

#: The longest a library file may be [lines] (the project's rule: split by responsibility beyond it).
MAX_LINES = 600


def test_no_library_file_is_longer_than_600_lines():
    long = {str(p.relative_to(PACKAGE)): n for p in _modules() if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"over {MAX_LINES} lines: {long}"


# --------------------------------------------------------------------------- import cycles
#
# An edge m → n for every import of a safenav module n that m can execute: top-level imports and
# imports inside functions alike (a function-level import runs when the function does, so it closes a
# cycle at run time just as a top-level one does; hiding a cycle inside a function is how the
# results → experiments cycle came about).  Imports under ``if TYPE_CHECKING:`` never run and are not
# edges.  ``from package import name`` is an edge to the submodule ``package.name`` when there is one,
# else to the package itself.  The compiled core (``safenav._core``) is a module that imports nothing
# of the Python package.

#: Compiled modules of the package (built by CMake, not in the source tree).
EXTENSIONS = ("safenav._core",)


def module_names(package: Path = PACKAGE) -> dict[str, Path]:
    """``dotted module name → file`` of every module of ``package`` (a package is its ``__init__.py``)."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _executed_nodes(tree: ast.AST):
    """Every node of ``tree`` except those under an ``if TYPE_CHECKING:`` branch (its ``else`` counts)."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for other in node.orelse:
                yield other
                yield from _executed_nodes(other)
            continue
        yield node
        yield from _executed_nodes(node)


def import_edges(name: str, source: str, modules, is_package: bool = False) -> set[str]:
    """The modules among ``modules`` that module ``name`` (source ``source``) imports (see above)."""
    here = name.split(".") if is_package else name.split(".")[:-1]
    edges = set()
    for node in _executed_nodes(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(here[:len(here) - node.level + 1] + ([node.module] if node.module else [])) \
                if node.level else node.module
            subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in modules]
            targets = subs + ([base] if len(subs) < len(node.names) else [])
        else:
            continue
        edges.update(t for t in targets if t in modules and t != name)
    return edges


def import_cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of the graph ``edges``: its strongly connected components of more than one
    module (Tarjan), each sorted, and any module importing itself."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while not comp or comp[-1] != v:
                comp.append(stack.pop())
                on_stack.discard(comp[-1])
            if len(comp) > 1 or v in edges.get(v, ()):
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def package_import_graph() -> dict[str, set[str]]:
    files = module_names()
    modules = set(files) | set(EXTENSIONS)
    graph = {m: import_edges(m, p.read_text(), modules, p.name == "__init__.py") for m, p in files.items()}
    return {**graph, **{m: set() for m in EXTENSIONS}}


def test_no_import_cycle_within_safenav():
    graph = package_import_graph()
    assert len(graph) > 40 and "safenav.vision.lanbloc" in graph["safenav.vision"]
    assert "safenav._core" in graph["safenav.vision.stereo"]     # from .. import _core
    assert import_cycles(graph) == []


def test_the_cycle_finder_sees_function_level_imports_and_skips_type_checking():
    modules = {"p", "p.a", "p.b", "p.c", "p.d"}
    edges = {
        "p": import_edges("p", "from . import a\n", modules, is_package=True),
        "p.a": import_edges("p.a", "import numpy\nfrom .b import f\n", modules),
        "p.b": import_edges("p.b", "def f():\n    from . import c\n    return c\n", modules),
        "p.c": import_edges("p.c", "from p.a import g\n", modules),
        "p.d": import_edges("p.d", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .a import g\n"
                                   "else:\n    from . import b\n", modules),
    }
    assert edges == {"p": {"p.a"}, "p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}, "p.d": {"p.b"}}
    assert import_cycles(edges) == [["p.a", "p.b", "p.c"]]
    edges["p.c"] = set()
    assert import_cycles(edges) == []
    assert import_cycles({"x": {"x"}}) == [["x"]]


# --------------------------------------------------------------------------- names kept by the splits

@pytest.mark.parametrize("module, names, home", [
    ("safenav.scenario", ("CameraParams", "DetectionParams", "BmmConfig", "NoiseParams", "PlannerParams",
                          "BufferParams", "NavigationParams", "Seeds", "MAX_STEPS", "_SECTIONS"),
     "safenav.scenario_params"),
    ("safenav.vision.render", ("StereoRig", "camera_rotation"), "safenav.vision.rig"),
    ("safenav.vision.render", ("StereoFrame",), "safenav.vision.frame"),
    ("safenav.vision.stereo", ("StereoCalibration",), "safenav.vision.calibration"),
    ("safenav.vision.stereo", ("DisparityScores", "disparity_scores", "MIDDLEBURY_THRESHOLDS"),
     "safenav.vision.scores"),
    ("safenav.vision.lanbloc", ("LanBLocResult", "STATUSES", "MISASSOCIATED", "OUTLIER"), "safenav.vision.sighting"),
    ("safenav.vision.lanbloc", ("PIPELINE_SGBM",), "safenav.vision.ranging"),
])
def test_split_modules_keep_their_names_importable(module, names, home):
    """A module split by responsibility still offers the names it had, as the same objects as their new home."""
    import importlib

    old, new = importlib.import_module(module), importlib.import_module(home)
    for name in names:
        assert getattr(old, name) is getattr(new, "SECTIONS" if name == "_SECTIONS" else name), name
