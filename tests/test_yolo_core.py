"""The core's YOLO detector (``safenav/yolo.hpp``, ``_core.YoloDetector``, ``_core.decode_yolo``)
against the Python one (``safenav.vision.detect``) on tiny ONNX graphs built with
``onnx.helper``: the same decode and class-wise NMS (bit for bit on random outputs), the same
letterbox and boxes on images of any size, grey or BGR; the model-file errors named; and
natural landmarks end to end in the core: its detections' boxes ranged by SGBM
(``localize_boxes``) give the Python pipeline's fix with the Python detector."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

pytest.importorskip("onnx")

from onnx import numpy_helper, helper  # noqa: E402

from safenav import _core  # noqa: E402
from safenav.vision.detect import FiducialDetector, YoloOnnxDetector, decode_yolo, letterbox  # noqa: E402
from safenav.vision.lanbloc import LanBLoc  # noqa: E402
from test_detect import IN, NC, _column, _save_model, clustered_output  # noqa: E402
from test_cpp_example import example_build, installed_prefix  # noqa: E402,F401
from test_lanbloc_cpp import (RIG, SCENES, _config, _fields, _front_end, _pair, _scene, _write_pgm,  # noqa: E402
                              example_exe)  # noqa: F401


def _model(path, const: np.ndarray, probe_entry: tuple | None, in_size: int = IN):
    """Output = const + mean(input) · e, e one-hot at ``probe_entry`` (or zero), from operators that
    OpenCV 4.6's ONNX importer runs (the core's), as well as pip's cv2: the channels' means
    (GlobalAveragePool), a MatMul that puts their mean at the probe's entry, a Reshape and an Add.
    (test_detect's ReduceMean graph runs in pip's cv2 only.)"""
    W = np.zeros((3, const.size), np.float32)
    if probe_entry is not None:
        W[:, np.ravel_multi_index(probe_entry, const.shape)] = 1.0 / 3.0
    nodes = [helper.make_node("GlobalAveragePool", ["images"], ["g"]),
             helper.make_node("Reshape", ["g", "s2"], ["g2"]),
             helper.make_node("MatMul", ["g2", "W"], ["p"]),
             helper.make_node("Reshape", ["p", "shape"], ["p3"]),
             helper.make_node("Add", ["p3", "const"], ["output0"])]
    inits = [numpy_helper.from_array(const, "const"), numpy_helper.from_array(W, "W"),
             numpy_helper.from_array(np.array([1, 3], np.int64), "s2"),
             numpy_helper.from_array(np.array(const.shape, np.int64), "shape")]
    return _save_model(path, nodes, inits, in_size, const.shape)


@pytest.fixture()
def tiny_model(tmp_path):
    """test_detect's tiny model (NMS within a class, not across; a score under the threshold; the
    probe) as a graph that both OpenCV versions run."""
    cols = [_column(20, 20, 10, 10, 0, 0.9), _column(21, 20, 10, 10, 0, 0.8), _column(21, 21, 10, 10, 1, 0.7),
            _column(45, 40, 8, 12, 2, 0.6), _column(45, 20, 8, 8, 1, 0.2), _column(10, 40, 6, 6, 2, 0.0)]
    const = np.stack(cols, axis=1)[None].astype(np.float32)
    return _model(tmp_path / "tiny.onnx", const, (0, 4 + 2, 5)), const


def _settings(**kw) -> _core.YoloSettings:
    s = _core.YoloSettings()
    for k, v in kw.items():
        setattr(s, k, v)
    return s


@pytest.mark.parametrize("seed", range(6))
def test_decode_is_pythons_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    nc, n = int(rng.integers(1, 6)), int(rng.integers(1, 500))
    out = clustered_output(rng, nc, n, min_side=0.0)
    out[0, 4:, rng.integers(0, n, 3)] = 0.5          # ties between classes and columns
    if n > 5:
        out[0, 0, 2], out[0, 4, 4] = np.nan, np.inf    # non-finite columns are dropped
    conf, iou = float(rng.uniform(0.05, 0.5)), float(rng.uniform(0.2, 0.8))
    boxes, scores, classes = decode_yolo(out, conf, iou)
    core = _core.decode_yolo(out, _settings(conf_threshold=conf, iou_threshold=iou))
    assert [d.class_id for d in core] == classes.tolist()
    assert [d.score for d in core] == scores.tolist()
    assert [tuple(d.box) for d in core] == [tuple(b) for b in boxes.tolist()]


@pytest.mark.parametrize("shape, channels", [((240, 320), 3), ((480, 640), 1), ((97, 331), 3), ((300, 61), 1),
                                             ((64, 64), 3), ((33, 1000), 1)])
def test_the_detector_letterboxes_and_boxes_as_python(tiny_model, shape, channels):
    path, _ = tiny_model
    py = YoloOnnxDetector(path, {0: 0, 1: 1, 2: 2}, input_size=IN, conf_threshold=0.25, iou_threshold=0.5)
    core = _core.YoloDetector(str(path), _settings(input_size=IN, conf_threshold=0.25, iou_threshold=0.5))
    assert core.num_classes == py.num_classes == NC
    rng = np.random.default_rng(shape[0])
    for img in (np.zeros(shape, np.uint8), np.full(shape, 255, np.uint8), rng.integers(0, 256, shape, np.uint8)):
        if channels == 3:
            img = np.dstack([img, img // 2, 255 - img]).astype(np.uint8)
        a, b = py.detect(img), core.detect(img)
        assert [d.class_id for d in b] == [d.class_id for d in a]
        # the probe's score is the mean of the letterboxed blob: the two OpenCV versions' resizing may
        # differ in a pixel's last bit
        np.testing.assert_allclose([d.score for d in b], [d.score for d in a], rtol=0, atol=1e-5)
        np.testing.assert_allclose([d.box for d in b], [d.box for d in a], rtol=0, atol=1e-9)


def test_model_errors_name_the_path_and_value(tmp_path, tiny_model):
    path, _ = tiny_model
    with pytest.raises(ValueError, match="YOLO model file not found: '.*nope/best.onnx'"):
        _core.YoloDetector(str(tmp_path / "nope" / "best.onnx"))
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"this is not a protobuf" * 10)
    with pytest.raises(ValueError, match="cannot read ONNX model '.*garbage.onnx'"):
        _core.YoloDetector(str(garbage), _settings(input_size=IN))
    for name, shape in (("classifier.onnx", (1, 10)), ("noclass.onnx", (1, 4, 6))):
        bad = _model(tmp_path / name, np.zeros(shape, np.float32), None)
        with pytest.raises(ValueError, match=rf"{name}' has output shape \({', '.join(map(str, shape))}\)"):
            _core.YoloDetector(str(bad), _settings(input_size=IN))
    for field, value, match in (("input_size", 16, "input_size = 16"), ("conf_threshold", 1.5, "conf_threshold = 1.5"),
                                ("iou_threshold", -0.1, "iou_threshold = -0.1"),
                                ("max_detections", 0, "max_detections = 0")):
        with pytest.raises(ValueError, match=match):
            _core.YoloDetector(str(path), _settings(**{"input_size": IN, field: value}))
    det = _core.YoloDetector(str(path), _settings(input_size=IN))
    with pytest.raises(ValueError, match="image is empty"):
        det.detect(np.zeros((0, 5), np.uint8))
    with pytest.raises(ValueError, match=r"\(H, W, 3\) BGR"):
        det.detect(np.zeros((5, 5, 4), np.uint8))
    with pytest.raises(ValueError, match=r"\(1, 4 \+ nc, N\)"):
        _core.decode_yolo(np.zeros((1, 4, 3), np.float32))


@pytest.fixture()
def marker_model(tmp_path):
    """A 'model' that finds the markers of a rendered scene (its constant output holds their boxes in
    letterboxed pixels, one class per landmark), and the Python pipeline's result with it
    (``LanBLoc(YoloOnnxDetector, ranging="sgbm")``)."""
    pose, placements = SCENES[0]
    world = _scene(pose, placements)
    left, right = _pair(world, pose)
    truth = FiducialDetector(world).detect(left)
    ids = [d.landmark_id for d in truth]
    size = 640
    _, (sx, sy), (px, py) = letterbox(left, size)
    cols = []
    for k, d in enumerate(truth):
        x0, y0, x1, y1 = d.box
        col = np.zeros(4 + len(ids), np.float32)
        col[:4] = (px + sx * (x0 + x1) / 2, py + sy * (y0 + y1) / 2, sx * (x1 - x0), sy * (y1 - y0))
        col[4 + k] = 0.9 - 0.01 * k
        cols.append(col)
    model = _model(tmp_path / "markers.onnx", np.stack(cols, axis=1)[None].astype(np.float32), None, size)
    classes = dict(enumerate(ids))
    ref = LanBLoc(world, RIG, YoloOnnxDetector(model, classes, input_size=size), ranging="sgbm").localize(left, right)
    assert ref.status == "ok" and len(ref.observations) == len(ids)
    return world, left, right, model, classes, size, ref


def test_natural_landmarks_in_the_core_give_the_python_pipelines_fix(marker_model):
    """The core's detector and SGBM ranging (``localize_boxes``) give the Python pipeline's fix."""
    world, left, right, model, classes, size, ref = marker_model
    core = _core.YoloDetector(str(model), _settings(input_size=size))
    fe = _front_end(world, ranging=_core.LanBLocRanging.SGBM, dictionary="")
    fix = fe.localize_boxes(left, right, [(classes[d.class_id], d.box) for d in core.detect(left)])
    assert fix.ok
    assert [o.landmark_id for o in fix.observations] == [o.landmark_id for o in ref.observations]
    np.testing.assert_allclose([o.range for o in fix.observations], [o.range for o in ref.observations], atol=1e-9)
    np.testing.assert_allclose(fix.position, ref.position, atol=1e-9)


def test_the_cpp_example_runs_natural_landmarks(marker_model, example_exe, tmp_path):
    """``lanbloc_frames`` with ``yolo`` and ``class`` lines: the model's detections, SGBM-ranged in a
    program that links safenav::core alone, give the Python pipeline's fix."""
    world, left, right, model, classes, size, ref = marker_model
    _write_pgm(tmp_path / "left.pgm", left)
    _write_pgm(tmp_path / "right.pgm", right)
    extra = f"yolo {model} {size}\n" + "".join(f"class {c} {lid}\n" for c, lid in classes.items() if c != 0)
    (tmp_path / "rig.txt").write_text(_config(world) + extra)
    proc = subprocess.run([str(example_exe), str(tmp_path / "rig.txt"), str(tmp_path / "left.pgm"),
                           str(tmp_path / "right.pgm")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert sum(line.startswith("detection ") for line in lines) == len(classes)
    obs = [_fields(line) for line in lines if line.startswith("observation ")]
    # class 0 is not mapped: not a landmark, the other detections are ranged
    assert [int(o["id"]) for o in obs] == [o.landmark_id for o in ref.observations if o.landmark_id != classes[0]]
    assert _fields(next(line for line in lines if line.startswith("fix ")))["status"] == "ok"
    (tmp_path / "bad.txt").write_text(_config(world) + f"yolo {tmp_path / 'missing.onnx'} {size}\n")
    proc = subprocess.run([str(example_exe), str(tmp_path / "bad.txt"), str(tmp_path / "left.pgm"),
                           str(tmp_path / "right.pgm")], capture_output=True, text=True)
    assert proc.returncode == 2 and "YOLO model file not found" in proc.stderr
