"""Bracketed paper citations follow docs/paper_map.md and name items that exist.

A citation such as ``[SafeNav-ext Alg. 4 l. 9]`` must name a paper version
that has that item: SafeNav's two versions number algorithms, lines, tables
and figures differently, so a bare ``[SafeNav …]`` is accepted only for what
both versions number alike (eqs. 1–19, Algs. 1–2, sections outside §V-A).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Items each tag may cite (docs/paper_map.md, "Sources" and "the two versions side by side").
VALID = {
    "SafeNav": {"eq": 19, "Alg": 2},
    "SafeNav-conf": {"eq": 19, "Alg": 3, "Table": 4, "Fig": 3},
    "SafeNav-ext": {"eq": 23, "Alg": 4, "Table": 5, "Fig": 5},
    "Placement": {"eq": 4, "Alg": 1, "Table": 1, "Fig": 9, "Lemma": 2, "Cor": 1, "Prop": 1, "LPP cond": 3},
}
# Last line of each algorithm, as numbered in the papers' text files.
LINES = {("SafeNav-conf", 1): 17, ("SafeNav-conf", 2): 8, ("SafeNav-conf", 3): 14,
         ("SafeNav-ext", 1): 21, ("SafeNav-ext", 2): 11, ("SafeNav-ext", 3): 12, ("SafeNav-ext", 4): 16}
SECTION = {
    "SafeNav": r"(?:I|II|III|IV(?:-[A-F]\d?)?|V(?:-[B-D]\d?)?|VI)",
    "SafeNav-conf": r"(?:I|II|III|IV(?:-[A-F]\d?)?|V(?:-A(?:\.[12](?:\((?:i|ii|iii)\))?)?|-[B-D]\d?)?|VI)",
    "SafeNav-ext": r"(?:I|II|III|IV(?:-[A-F]\d?)?|V(?:-A(?:[1-3](?:\((?:i|ii|iii)\))?)?|-[B-D]\d?)?|VI)",
    "Placement": r"(?:I(?:-[A-C])?|II(?:-[AB])?|III(?:-[AB])?|IV)",
}
ROMAN = {"I": 1, "II": 2, "III": 3, "IV": 4, "V": 5}
KINDS = {"eq.": "eq", "eqs.": "eq", "Alg.": "Alg", "Algs.": "Alg", "Table": "Table", "Tables": "Table",
         "Fig.": "Fig", "Figs.": "Fig", "Lemma": "Lemma", "Cor.": "Cor", "Prop.": "Prop", "LPP cond.": "LPP cond"}
TAG = r"SafeNav-conf|SafeNav-ext|SafeNav|Placement"
BRACKET = re.compile(rf"\[((?:{TAG})(?=[\s\]])[^\]\[]*)\]")
PART = re.compile(rf"^(?:({TAG}) )?(?:(§)\s*(\S+)|({'|'.join(map(re.escape, KINDS))}) ([0-9IVX]+)(?:–([0-9IVX]+))?"
                  r"(?: (l\.|ll\.) (\d+)(?:–(\d+))?)?)$")


def citation_errors(text: str) -> list[str]:
    """Problems of each ``[Tag …]`` citation in ``text`` (comment markers and line breaks allowed inside)."""
    errors = []
    for m in BRACKET.finditer(text):
        body = " ".join(re.sub(r"^\s*(?:///?<?|#)\s?", "", ln) for ln in m.group(1).splitlines()).strip()
        body = re.sub(r"\s+", " ", body)
        tag = None
        for part in body.split(", "):
            p = PART.match(part)
            if not p:
                errors.append(f"[{body}]: cannot read {part!r}")
                break
            tag = p.group(1) or tag
            if p.group(2):
                if not re.fullmatch(SECTION[tag], p.group(3)):
                    errors.append(f"[{body}]: {tag} has no section §{p.group(3)} (or it needs a version)")
                continue
            kind = KINDS[p.group(4)]
            lo, hi = (ROMAN.get(g, int(g) if g and g.isdigit() else 0) for g in (p.group(5), p.group(6) or p.group(5)))
            top = VALID[tag].get(kind, 0)
            if not 1 <= lo <= hi <= top:
                errors.append(f"[{body}]: {tag} has no {kind} {p.group(5)}" + (f"–{p.group(6)}" if p.group(6) else ""))
            elif p.group(7):
                last = LINES.get((tag, lo))
                line_hi = int(p.group(9) or p.group(8))
                if last is None or lo != hi or not 1 <= int(p.group(8)) <= line_hi <= last:
                    errors.append(f"[{body}]: {tag} Alg. {lo} has no line {p.group(8)} (lines need a version)")
    return errors


def _sources():
    globs = ("cpp/include/safenav/*.hpp", "cpp/src/**/*.[ch]pp", "cpp/bindings/*.[ch]pp", "python/safenav/**/*.py",
             "docs/*.md", "README.md")
    for g in globs:
        for path in sorted(ROOT.glob(g)):
            if path.name != "paper_map.md":  # it shows the syntax with placeholders
                yield path


def test_every_bracketed_citation_names_an_existing_item():
    found, errors = 0, []
    for path in _sources():
        text = path.read_text(encoding="utf-8")
        found += len(BRACKET.findall(text))
        errors += [f"{path.relative_to(ROOT)}: {e}" for e in citation_errors(text)]
    assert not errors, "\n".join(errors)
    assert found >= 30, f"only {found} bracketed citations found: is the pattern still right?"


@pytest.mark.parametrize("good", [
    "[SafeNav eq. 18]", "[SafeNav eqs. 3–9]", "[SafeNav Alg. 2]", "[SafeNav §IV-A]", "[SafeNav-ext eqs. 20–23]",
    "[SafeNav-ext Alg. 4 l. 9]", "[SafeNav-conf Alg. 3 ll. 5–7]", "[SafeNav-conf Table II]",
    "[SafeNav-ext Tables II–III]", "[SafeNav-ext Fig. 3]", "[SafeNav-ext §V-A3(ii)]", "[SafeNav-conf §V-A.2(i)]",
    "[SafeNav eqs. 15–19, SafeNav-ext Alg. 3]", "[Placement Lemma 2, eqs. 1–2]", "[Placement Cor. 1, eq. 4]",
    "[Placement LPP cond. 2]", "[Placement §II-A]", "[Placement Prop. 1]", "[SafeNav-conf\n// Alg. 3]",
])
def test_valid_citations_pass(good):
    assert citation_errors(good) == []


@pytest.mark.parametrize("bad", [
    "[SafeNav Alg. 3]",            # RAw-RRT* in ext, the navigation loop in conf
    "[SafeNav Alg. 1 l. 13]",      # line numbers differ between the versions
    "[SafeNav Table I]",           # tables differ between the versions
    "[SafeNav Fig. 3]",
    "[SafeNav eq. 21]",            # numbered in the extended version only
    "[SafeNav §V-A3(i)]",          # §V-A's subsections differ
    "[SafeNav-conf Alg. 4]", "[SafeNav-conf Table V]", "[SafeNav-conf eq. 20]", "[SafeNav-ext Alg. 1 l. 22]",
    "[Placement eq. 5]", "[Placement Alg. 2]", "[Placement Lemma 3]", "[SafeNav-ext Algorithm 3]",
])
def test_ambiguous_or_missing_citations_fail(bad):
    assert citation_errors(bad), bad


# Files whose citations follow the convention without brackets too: SafeNav items
# that the two versions number differently must name the version here as well.
UNBRACKETED_CHECKED = ("README.md", "docs/*.md", "cpp/src/navigation.cpp", "cpp/src/placement_*.cpp",
                       "cpp/bindings/navigation.cpp", "cpp/include/safenav/navigation.hpp",
                       "python/safenav/navigation.py", "python/safenav/datasets.py", "python/safenav/cli.py",
                       "python/safenav/planning.py", "python/safenav/runner.py", "python/safenav/placement/*.py",
                       "python/safenav/experiments/*.py", "python/safenav/vision/*.py",
                       # fixed after the corridor/world/measurement moves (docs/paper_map.md, appendix)
                       "cpp/include/safenav/metrics.hpp", "cpp/include/safenav/world.hpp",
                       "cpp/include/safenav/measurement.hpp", "cpp/src/corridor.cpp", "cpp/src/planning.cpp",
                       "cpp/src/world.cpp", "cpp/src/placement_internal.hpp", "cpp/bindings/corridor.cpp",
                       "python/safenav/geometry.py", "python/safenav/metrics.py", "python/safenav/world.py",
                       "python/safenav/scenario.py", "python/safenav/scenario_params.py")
# The old, ambiguous forms (docs/paper_map.md, appendix), each with the qualifiers that make it unambiguous.
OLD_FORMS = {
    "eqs. 20-23 without a version": re.compile(r"(?<!ext )(?<!SafeNav-ext )\beqs?\. 2[0-3]\b(?! \(extended)"),
    "a §V-A subsection without a version":
        re.compile(r"(?<!SafeNav-ext )(?<!SafeNav-conf )(?<!-ext §)(?:\bsection |\bSafeNav |§)V-A\b"),
    "an algorithm line without a version": re.compile(r"\(lines? \d+(?:–\d+)?\)|Algorithm \d, lines? \d"),
    "Algorithm 3 or 4 without a version":
        re.compile(r"(?<!extended paper's )(?<!conference's )\bAlgorithms? (?:[0-9, and]+ )?[34]\b"
                   r"(?! of the (?:extended|conference))"),
}


def old_citation_forms(text: str) -> list[str]:
    """The old unbracketed forms in ``text`` (whitespace, line breaks included, read as one space)."""
    flat = re.sub(r"\s+", " ", text)
    return [f"{what}: …{flat[max(m.start() - 40, 0):m.end() + 20]}…"
            for what, rx in OLD_FORMS.items() for m in rx.finditer(flat)]


def test_fixed_files_have_no_old_unbracketed_citations():
    paths = [p for g in UNBRACKETED_CHECKED for p in sorted(ROOT.glob(g)) if p.name != "paper_map.md"]
    assert len(paths) >= 20, [str(p) for p in paths]
    errors = [f"{p.relative_to(ROOT)}: {e}" for p in paths for e in old_citation_forms(p.read_text(encoding="utf-8"))]
    assert not errors, "\n".join(errors)


@pytest.mark.parametrize("old", [
    "ADE (eq. 21)", "SafeNav eqs. 20-23", "(SafeNav V-A: clusters of ≥ 3)", "the world (section V-A)",
    "kept (line 13)", "// Obstacles ahead (Algorithm 4, lines 7–9).", "Algorithm 4, line 8: whether",
    "RAw-RRT* (Algorithm 3)", "Runs SafeNav trials (Algorithms 1, 2 and 4)", "# Algorithm 4\n(replanning)",
])
def test_old_unbracketed_forms_are_caught(old):
    assert old_citation_forms(old), old


@pytest.mark.parametrize("ok", [
    "[SafeNav-ext eqs. 20–23]", "ext eq. 23", "eq. 21 (extended paper)", "SafeNav-ext §V-A3(i)",
    "([SafeNav-ext Alg. 1 l. 17], conf l. 13)", "(line 17; conference 13)", "(Algorithm 4 of the extended paper)",
    "Algorithm 3 of the conference version", "the extended paper's Algorithm 4", "SafeNav eqs. 15–19",
])
def test_qualified_forms_pass(ok):
    assert old_citation_forms(ok) == [], ok


# --------------------------------------------------------------------------- the map's Python names

PYTHON_NAME = re.compile(r"`(safenav(?:\.[A-Za-z_][A-Za-z0-9_]*)+)")


def resolve(name: str):
    """The object a dotted ``safenav.…`` name denotes: the longest importable module, then attributes."""
    import importlib

    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for p in parts[i:]:
            obj = getattr(obj, p)
        return obj
    raise ImportError(name)


def test_every_python_name_in_the_paper_map_exists():
    text = (ROOT / "docs" / "paper_map.md").read_text(encoding="utf-8")
    names = sorted(set(PYTHON_NAME.findall(text)))
    assert len(names) > 50
    missing = []
    for n in names:
        try:
            resolve(n)
        except (ImportError, AttributeError) as exc:
            missing.append(f"{n}: {exc}")
    assert not missing, "\n".join(missing)


def test_the_paper_map_cites_only_files_in_the_repository():
    text = (ROOT / "docs" / "paper_map.md").read_text(encoding="utf-8")
    assert "DESIGN.md" not in text
    for doc in re.findall(r"`(docs/[\w.]+\.md)`", text):
        assert (ROOT / doc).is_file(), doc


def test_resolve_names_what_is_missing():
    import safenav.vision.lanbloc as lb

    assert resolve("safenav.vision.lanbloc.LanBLoc.localize") is lb.LanBLoc.localize
    for gone in ("safenav.reproduce.run_synthetic", "safenav.plots.plot_field", "safenav.vision.Nothing"):
        with pytest.raises((ImportError, AttributeError)):
            resolve(gone)
