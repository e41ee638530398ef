"""The mission certificate's report and ``safenav plan``'s certificate
options: the text, ``certificate.json`` and ``certificate.md`` of
:func:`safenav.certify.certify_paths`'s certificates."""

from __future__ import annotations

import argparse

from . import console
from .certify import CANNOT, CERTIFIED, NEEDS_LANDMARKS, certify_paths
from .metrics import path_length

__all__ = ["report_lines", "add_arguments", "plan_certificates"]


def report_lines(certs: list) -> list[str]:
    """One paragraph per path and a total line."""
    lines = []
    for c in certs:
        head = f"{c.name}: {c.status.upper()}"
        if c.status == NEEDS_LANDMARKS:
            head += f" ({c.n_added} landmark(s))"
        lines.append(f"{head}; ε = {c.epsilon:g}" if not len(c.path) else
                     f"{head}; {c.planner} path, {path_length(c.path):.1f} m, ε = {c.epsilon:g}, k = {c.k:.3g} "
                     f"(N = {c.exposures:g})")
        given = "as given" if c.proposed_for is None else \
            f"as given (the {path_length(c.proposed_for):.1f} m path the landmarks were proposed for)"
        for label, ch in ((given, c.given), (f"with {c.n_added} added", c.final)):
            if ch is not None:
                lines.append(f"  {label}: σ max {ch.sigma_max:.3g} m at s = {ch.sigma_max_s:.1f} m "
                             f"({ch.sigma_max_xy[0]:.1f}, {ch.sigma_max_xy[1]:.1f}), P(collision) "
                             f"{ch.collision_probability:.3g} (union bound {ch.union_bound:.3g}), min room "
                             f"{ch.min_room:.3g} m at s = {ch.min_room_s:.1f} m (robust camera)")
                if ch.expected is not None:
                    e = ch.expected
                    lines.append(f"  {' ' * len(label)}  expected (the vehicle's camera): σ max {e.sigma_max:.3g} "
                                 f"m at s = {e.sigma_max_s:.1f} m, P(collision) {e.collision_probability:.3g}, "
                                 f"min room {e.min_room:.3g} m")
                lines.extend(f"  {' ' * len(label)}  {_nominal_line(m, a)}" for m, a in ch.along.items())
        lines.append(f"  {c.reason}")
    n = {s: sum(c.status == s for c in certs) for s in (CERTIFIED, NEEDS_LANDMARKS, CANNOT)}
    lines.append(f"certificate: {n[CERTIFIED]} certified as given, {n[NEEDS_LANDMARKS]} need landmarks "
                 f"({sum(c.n_added for c in certs if c.status == NEEDS_LANDMARKS)} landmarks in all), "
                 f"{n[CANNOT]} cannot be certified")
    return lines


def _nominal_line(method: str, c) -> str:
    """One method's nominal run (``Check.along``) in words: the certificate requires its
    collision probability at most ε, and reports its room."""
    worst = min(c.min_room, c.expected.min_room)
    pc = max(c.collision_probability, c.expected.collision_probability)
    text = (f"along {method}'s nominal run: P(collision) {pc:.3g} "
            + ("(within ε)" if c.certified else "> ε: not certified")
            + f", min room {worst:.3g} m at s = {c.min_room_s:.1f} m ({c.min_room_xy[0]:.1f}, {c.min_room_xy[1]:.1f})")
    return text + (" (below k·σ: the controller cuts inside the path there)" if worst <= 0 and c.certified else "")


def _markdown(certs: list, proposed_file: str | None) -> str:
    rows = ["| path | status | planner | landmarks added | σ max [m] (at s) | expected σ max [m] | P(collision) | "
            "expected P(collision) | min room [m] | reason |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for c in certs:
        ch = c.final or c.given
        e = ch.expected if ch is not None and ch.expected is not None else None
        cells = ("–", "–", "–", "–", "–") if ch is None else (
            f"{ch.sigma_max:.3g} ({ch.sigma_max_s:.1f} m)", f"{e.sigma_max:.3g}" if e else "–",
            f"{ch.collision_probability:.3g}", f"{e.collision_probability:.3g}" if e else "–", f"{ch.min_room:.3g}")
        given = "" if c.given is None or c.final is None else \
            f" (as given: σ max {c.given.sigma_max:.3g} m, P {c.given.collision_probability:.3g})"
        runs = "; ".join(_nominal_line(m, a) for m, a in ch.along.items()) if ch is not None else ""
        rows.append(f"| {c.name} | {c.status} | {c.planner} | {c.n_added} | {' | '.join(cells)} | {c.reason}{given}"
                    + (f"; {runs}" if runs else "") + " |")
    text = ("# Mission certificate\n\nσ max, P(collision) and min room: the robust camera's belief, which the "
            "certificate checks; expected: the vehicle's own camera, the σ the vehicle will get.\n\n"
            + "\n".join(rows) + "\n")
    if proposed_file:
        text += f"\nThe scenario with the proposed landmarks: `{proposed_file}`.\n"
    return text


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``safenav plan``'s certificate options (called by the command line's parser)."""
    from .validation import arg_at_least, arg_positive

    parser.add_argument("--planner", choices=["raw", "belief"], default="raw",
                        help="raw: the paper's RAw-RRT* (default); belief: the belief-aware RRBT planner at "
                             "k(ε), with the RAw-RRT* path as a guide")
    parser.add_argument("--no-landmarks", action="store_true",
                        help="certify only; propose no landmarks for the paths that fail")
    parser.add_argument("--landmark-spacing", type=arg_positive, default=2.0,
                        help="candidate grid spacing for proposed landmarks [m] (default 2)")
    parser.add_argument("--landmark-rounds", type=arg_at_least(1), default=3,
                        help="placement rounds at most per path (default 3)")


def plan_certificates(args, scenario, raw_paths: dict, out) -> list:
    """``safenav plan``: certify the paths, print the report, write
    ``certificate.json``, ``certificate.md`` and, when landmarks were
    proposed, ``proposed_scenario.toml`` in ``out`` (through
    :mod:`safenav.results`' atomic writers)."""
    from pathlib import Path

    from .results import write_json, write_text
    from .scenario import save_scenario

    out = Path(out)
    with console.task(f"certifying {len(raw_paths)} path(s) against ε = "
                      f"{scenario.navigation.collision_probability:g}"):
        certs, proposed = certify_paths(scenario, raw_paths, planner=args.planner, propose=not args.no_landmarks,
                                        rounds=args.landmark_rounds, spacing=args.landmark_spacing)
    file = None
    if proposed is not None:
        file = "proposed_scenario.toml"
        save_scenario(proposed, out / file)
    print("\n".join(report_lines(certs)))
    if file:
        print(f"proposed scenario: {out / file} (safenav run --scenario {out / file})")
    write_json(out / "certificate.json", {"scenario": scenario.name,
                                          "epsilon": scenario.navigation.collision_probability,
                                          "proposed_scenario": file, "paths": [c.to_dict() for c in certs]})
    write_text(out / "certificate.md", _markdown(certs, file))
    return certs
