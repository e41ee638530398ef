"""``safenav place``, the landmark placement command line: the example end to end
(covered, certified by the exact check, the bearing-only EIF inside its 3-sigma
bounds; the ILP on the same route) and the errors that name a bad input file."""

from __future__ import annotations

import numpy as np

from safenav import placement as P

def test_cli_end_to_end_on_the_example(tmp_path):
    import json
    from importlib.resources import files

    from safenav.cli import main

    example = files("safenav") / "data" / "placement_example.toml"
    out = tmp_path / "place"
    assert main(["place", str(example), "--out", str(out), "--simulate"]) == 0
    data = json.loads((out / "placement.json").read_text())
    assert (out / "placement.png").stat().st_size > 10_000 and (out / "placement_errors.png").exists()
    assert data["covered"] and data["corners"] and data["check"]["min_in_view"] >= 2
    lm = np.array(data["landmarks"])
    assert len(lm) == data["n_landmarks"] > 0
    rep = P.check_coverage(data["route"], lm, P.CameraParams(**data["camera"]), k=2, corners=True)
    assert rep.min_count >= 2 and rep.min_distance > 0.05
    assert min(data["simulation"]["inside_3sigma"].values()) >= 0.9
    # the route is the tour through the example's targets, first to last
    assert data["route"][0] == [0.6, 0.8] and data["route"][-1] == [1.2, 7.6]
    # optimal on the same file, JSON input with an explicit route
    src = {"route": data["route"], "camera": data["camera"], "placement": {"method": "optimal"}}
    (tmp_path / "in.json").write_text(json.dumps(src))
    assert main(["place", str(tmp_path / "in.json"), "--out", str(tmp_path / "opt"), "--no-corners"]) == 0
    opt = json.loads((tmp_path / "opt" / "placement.json").read_text())
    assert opt["method"] == "optimal" and opt["optimal"] and opt["n_landmarks"] <= data["n_landmarks"]


def test_cli_bad_files_give_clear_errors(tmp_path, capsys):
    from safenav.cli import main

    cases = {
        "missing.toml": None,
        "bad.toml": "targets = [[0, 0], [1, 1]]\n[camera]\nangle_deg = 270\n",
        "both.toml": "targets = [[0, 0], [1, 1]]\nroute = [[0, 0], [1, 1]]\n",
        "unknown.toml": "targets = [[0, 0], [1, 1]]\n[camera]\nzoom = 2\n",
        "sparse.toml": "route = [[0, 0], [3, 0]]\n[candidates]\nspacing = 3.0\n",
        "broken.json": "{not json",
    }
    expect = {
        "missing.toml": "does not exist", "bad.toml": "angle alpha = 270", "both.toml": "exactly one of",
        "unknown.toml": "unknown key camera.zoom", "sparse.toml": "cannot keep 2 landmarks in view on edge 0",
        "broken.json": "cannot parse",
    }
    for name, text in cases.items():
        f = tmp_path / name
        if text is not None:
            f.write_text(text)
        assert main(["place", str(f), "--out", str(tmp_path / "o")]) == 2
        assert expect[name] in capsys.readouterr().err
