"""``safenav place FILE``: landmark placement from the command line.

Reads targets (or a route), the camera parameters, the candidate set and
optional obstacles that hide landmarks (``[obstacles]``: ``circles = [[x, y,
radius], ...]``, ``polygons = [[[x, y], ...], ...]``) from
a TOML or JSON file (see ``python/safenav/data/placement_example.toml``),
places landmarks (:mod:`safenav.placement`) and writes ``placement.json`` and
``placement.png`` (plus ``placement_errors.png`` with ``--simulate``) through
:mod:`safenav.results`, ending with ``manifest.json``.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
from pathlib import Path

_TOP = {"targets", "route", "camera", "placement", "candidates", "obstacles"}
_SECTIONS = {
    "camera": {"range", "angle_deg", "clearance", "fov"},
    "placement": {"k", "method", "corners", "occlusion"},
    "candidates": {"spacing", "margin", "points"},
    "obstacles": {"circles", "polygons"},
}


def register(sub, *, parents=(), positive=int, run_folder, wrote) -> None:
    """Add the ``place`` subcommand to the CLI's subparsers (``parents``: the
    options every command shares; ``positive``: the parser of integers >= 1;
    ``run_folder(args, out, seed=)`` and ``wrote(run)``: the CLI's output
    folder and its closing status line)."""
    s = sub.add_parser("place", parents=list(parents),
                       help="place landmarks along a route or through targets (landmark placement paper)",
                       description="Place the fewest landmarks so that a camera on the route always sees k of them.")
    s.add_argument("file", help="TOML or JSON input: targets or route, [camera], [placement], [candidates]")
    s.add_argument("--out", default="out/place", help="folder for placement.json and placement.png (default out/place)")
    s.add_argument("--method", choices=["greedy", "reuse", "optimal"], help="override [placement].method")
    s.add_argument("--k", type=positive, help="override [placement].k")
    s.add_argument("--corners", action=argparse.BooleanOptionalAction, help="override [placement].corners (--corners / --no-corners)")
    s.add_argument("--occlusion", action=argparse.BooleanOptionalAction,
                   help="obstacles ([obstacles] circles and polygons) hide landmarks (default: on when the input "
                        "has obstacles; override [placement].occlusion)")
    s.add_argument("--allow-uncovered", action="store_true",
                   help="write the best-effort placement instead of failing when a stretch cannot be covered")
    s.add_argument("--simulate", action="store_true",
                   help="also drive the route with the bearing-only EIF and plot the errors with 3-sigma bounds")
    s.add_argument("--seed", type=int, default=0, help="seed of the tour restarts and the simulation (default 0)")
    s.set_defaults(func=functools.partial(_place, run_folder=run_folder, wrote=wrote))


def load_input(path) -> dict:
    """Read and validate a placement input file; errors name the file and field."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"placement input {str(p)!r} does not exist")
    text = p.read_bytes()
    try:
        if p.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            import tomllib

            data = tomllib.loads(text.decode("utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"{p}: cannot parse: {exc}") from exc
    if not isinstance(data, dict):
        raise ValueError(f"{p}: the top level must be a table, got {type(data).__name__}")
    unknown = set(data) - _TOP
    if unknown:
        raise ValueError(f"{p}: unknown key {sorted(unknown)[0]!r} (known: {', '.join(sorted(_TOP))})")
    for sec, keys in _SECTIONS.items():
        v = data.get(sec, {})
        if not isinstance(v, dict):
            raise ValueError(f"{p}: [{sec}] must be a table, got {v!r}")
        bad = set(v) - keys
        if bad:
            raise ValueError(f"{p}: unknown key {sec}.{sorted(bad)[0]} (known: {', '.join(sorted(keys))})")
    if ("targets" in data) == ("route" in data):
        raise ValueError(f"{p}: give exactly one of 'targets' and 'route'")
    return data


def _place(args, *, run_folder, wrote) -> int:
    from .. import console
    from .. import placement as P
    from ..validation import as_array
    from ..results import write_json

    path = Path(args.file)
    data = load_input(path)
    cam = P.CameraParams(**data.get("camera", {}))
    opts = data.get("placement", {})
    k = args.k if args.k is not None else opts.get("k", 2)
    method = args.method or opts.get("method", "greedy")
    corners = args.corners if args.corners is not None else opts.get("corners", False)
    if not isinstance(corners, bool):
        raise ValueError(f"{path}: placement.corners = {corners!r} must be true or false")
    obstacles = data.get("obstacles") or None
    occlusion = args.occlusion if args.occlusion is not None else opts.get("occlusion", obstacles is not None)
    if not isinstance(occlusion, bool):
        raise ValueError(f"{path}: placement.occlusion = {occlusion!r} must be true or false")
    if occlusion and obstacles is None:
        raise ValueError(f"{path}: occlusion is on but the input has no [obstacles]")
    occ = P.occluders(obstacles) if occlusion else None
    key = "route" if "route" in data else "targets"
    pts = as_array(key, data[key], (None, 2))
    cs = data.get("candidates", {})
    if "points" in cs:
        if "spacing" in cs or "margin" in cs:
            raise ValueError(f"{path}: candidates.points excludes candidates.spacing and candidates.margin")
        cand = as_array("candidates.points", cs["points"], (None, 2))
    else:
        spacing = cs.get("spacing", P.PAPER_SPACING)
        margin = cs.get("margin", cam.range)
        for name, v in (("candidates.spacing", spacing), ("candidates.margin", margin)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"{path}: {name} = {v!r} must be a finite number >= 0")
        cand = P.candidate_grid(pts.min(axis=0), pts.max(axis=0), spacing, margin=margin)
    kw = dict(k=k, corners=corners, method=method, seed=args.seed, allow_uncovered=args.allow_uncovered,
              obstacles=occ)
    out = Path(args.out)
    with run_folder(args, out, seed=args.seed) as run:
        with console.task(f"placing landmarks ({method}, k = {k}, {len(cand)} candidates"
                          f"{', occlusion' if occ is not None else ''})"):
            if key == "route":
                res = P.place_through_targets(None, cand, cam, route=pts, **kw)
            else:
                res = P.place_through_targets(pts, cand, cam, **kw)
        summary = res.to_dict()
        summary["input"] = str(path)
        rep = res.check()
        summary["check"] = {"min_in_view": int(rep.min_count), "min_distance": float(rep.min_distance)}
        sim = None
        if args.simulate:
            with console.task("bearing-only EIF along the route"):
                sim = P.simulate(res.route, res.landmarks, cam, seed=args.seed)
            summary["simulation"] = {"duration_s": float(sim.t[-1]), "inside_3sigma": sim.inside_3sigma(),
                                     "fraction_below_k_in_view": sim.gap_fraction(res.k)}
            P.plot_simulation(sim, out / "placement_errors.png")
        write_json(out / "placement.json", summary)
        P.plot_placement(res, out / "placement.png", simulation=sim)
        print(f"{res.method}{' (occlusion)' if occ is not None else ''}: {res.count} landmarks for {len(res.route) - 1} edges "
              f"(route {P.tour_length(res.route):.2f} m, {len(cand)} candidates, {len(res.too_close)} within p), "
              f"{'covered' if res.covered else f'{len(res.uncovered)} stretches uncovered'}; min in view "
              f"{rep.min_count}")
        if sim is not None:
            ins = sim.inside_3sigma()
            print("EIF within 3 sigma: " + ", ".join(f"{n} {100 * v:.1f}%" for n, v in ins.items()))
        wrote(run)
    return 0
