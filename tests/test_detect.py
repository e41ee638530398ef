"""Landmark recognition: fiducial detection on generated and rendered
images, YOLOv8/11 ONNX decoding + class-wise NMS on tiny ONNX graphs built here
with ``onnx.helper`` (no model download), and the model-file errors."""

from __future__ import annotations

import numpy as np
import pytest

import cv2

onnx = pytest.importorskip("onnx")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

import safenav  # noqa: E402,F401  (builds the core)
from safenav.vision.detect import (Detection, FiducialDetector, YoloOnnxDetector, aruco_dictionary,  # noqa: E402
                            decode_yolo, letterbox, marker_image)
from safenav.vision.render import StereoRenderer, StereoRig  # noqa: E402
from safenav.world import Landmark  # noqa: E402


# --------------------------------------------------------------------------- fiducials

def _canvas_with_markers(dictionary, placements, size=(480, 640), cell_px=6):
    """Paste markers at integer offsets; returns the image and each marker's black-square box."""
    img = np.full(size, 200, np.uint8)
    img[::7] = 180  # a little structure
    boxes = {}
    for mid, (x, y) in placements.items():
        m = marker_image(dictionary, mid, cell_px=cell_px, border_cells=1)
        img[y:y + m.shape[0], x:x + m.shape[1]] = m
        b = cell_px  # the white quiet zone
        s = m.shape[0] - 2 * b
        # pixel centres of the black square's outer pixels are x+b .. x+b+s-1; its edges are half a pixel out
        boxes[mid] = (x + b - 0.5, y + b - 0.5, x + b + s - 0.5, y + b + s - 0.5)
    return img, boxes


@pytest.mark.parametrize("dictionary", ["DICT_4X4_100", "DICT_6X6_250", "APRILTAG_36h11"])
def test_fiducials_on_generated_images_give_ids_and_boxes(dictionary):
    placements = {3: (20, 30), 17: (300, 60), 42: (150, 250), 7: (450, 300)}
    img, boxes = _canvas_with_markers(dictionary, placements)
    det = FiducialDetector(dictionary=dictionary)
    found = det.detect(img)
    assert sorted(d.landmark_id for d in found) == sorted(placements)
    for d in found:
        assert d.score == 1.0 and d.class_id == d.landmark_id
        np.testing.assert_allclose(d.box, boxes[d.landmark_id], atol=0.75)
        assert d.corners.shape == (4, 2)
    # a BGR image gives the same detections
    bgr = det.detect(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
    assert [d.box for d in bgr] == [d.box for d in found]


def test_landmark_map_translates_marker_ids_and_skips_others():
    img, _ = _canvas_with_markers("DICT_4X4_100", {3: (20, 30), 17: (300, 60), 42: (150, 250)})
    det = FiducialDetector({3: 103, 42: 7})
    found = det.detect(img)
    assert sorted((d.class_id, d.landmark_id) for d in found) == [(3, 103), (42, 7)]
    assert det.last_unmapped == [17]


def test_landmark_map_from_world_names_classes():
    world = safenav.World(landmarks=(Landmark(3, (10.0, 10.0, 2.0), "tower", 1),
                                     Landmark(42, (20.0, 10.0, 2.0), "bridge", 1)))
    img, _ = _canvas_with_markers("DICT_4X4_100", {3: (20, 30), 17: (300, 60), 42: (150, 250)})
    found = FiducialDetector(world).detect(img)
    assert {(d.landmark_id, d.class_name) for d in found} == {(3, "tower"), (42, "bridge")}


def test_fiducial_errors_name_the_value():
    with pytest.raises(ValueError, match="DICT_9X9"):
        FiducialDetector(dictionary="DICT_9X9_50")
    with pytest.raises(ValueError, match="marker id 500"):
        FiducialDetector({500: 1}, dictionary="DICT_4X4_100")
    with pytest.raises(ValueError, match="-2"):
        FiducialDetector({1: -2})
    det = FiducialDetector()
    with pytest.raises(ValueError, match="empty"):
        det.detect(np.zeros((0, 10), np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        det.detect(np.zeros((10, 10), np.float32))
    with pytest.raises(ValueError, match="shape"):
        det.detect(np.zeros((4, 4, 4, 4), np.uint8))
    with pytest.raises(ValueError, match="marker_id"):
        marker_image("DICT_4X4_50", 50)


def test_fiducials_on_a_rendered_frame_match_the_visible_markers():
    """Every marker the renderer reports as wholly visible (>= 16 px a side) is detected,
    with its box around the pinhole projection of its corners (within 1.5 px: cornerSubPix slides
    up to ~1.3 px inside a convex corner blurred by the optics' point spread, see test_render)."""
    world = safenav.default_scenario().world
    r = StereoRenderer(world, StereoRig())
    c = world.cluster_centroid(6)
    pose = (c[0] - 15.0, c[1] - 3.0, 0.2)
    left, right = r.render(pose)
    visible = r.visible(pose, min_side_px=16)
    assert len(visible) >= 3
    corners = r.marker_corners(pose)
    det = FiducialDetector(world)
    for img, cam in ((left, "left"), (right, "right")):
        found = {d.landmark_id: d for d in det.detect(img)}
        assert set(visible) <= set(found)
        assert set(found) <= set(r.visible(pose))  # nothing invented
        for lid in visible:
            uv, _ = r.project(pose, corners[lid], cam)
            np.testing.assert_allclose(found[lid].box, [*uv.min(axis=0), *uv.max(axis=0)], atol=1.5)


# --------------------------------------------------------------------------- YOLO decode + NMS

def _iou(a, b):
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[2], b[2]), min(a[3], b[3])
    inter = max(0.0, x1 - x0) * max(0.0, y1 - y0)
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


def _reference_decode(out, conf, iou):
    """Brute force: argmax class, threshold, greedy NMS per class (Ultralytics' non_max_suppression)."""
    pred = out[0]
    keep = []
    for c in range(pred.shape[0] - 4):
        cand = []
        for j in range(pred.shape[1]):
            s = pred[4:, j]
            if np.argmax(s) == c and s[c] > conf:
                cx, cy, w, h = pred[:4, j]
                cand.append((float(s[c]), (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)))
        cand.sort(key=lambda t: -t[0])
        chosen = []
        for s, b in cand:
            if all(_iou(b, kb) <= iou for _, kb in chosen):
                chosen.append((s, b))
        keep += [(s, b, c) for s, b in chosen]
    keep.sort(key=lambda t: -t[0])
    return keep


def clustered_output(rng, nc: int, n: int, min_side: float = 20.0) -> np.ndarray:
    """A YOLO output (1, 4 + nc, n): clusters of jittered boxes (so that NMS has work to do), sides
    from ``min_side`` to 60 px, scores cubed uniforms."""
    out = np.zeros((1, 4 + nc, n), np.float32)
    centres = rng.uniform(50, 590, (12, 2))
    k = rng.integers(0, 12, n)
    out[0, 0:2] = (centres[k] + rng.normal(0, 6, (n, 2))).T
    out[0, 2:4] = rng.uniform(min_side, 60, (2, n))
    out[0, 4:] = rng.uniform(0, 1, (nc, n)) ** 3
    return out


def test_decode_matches_brute_force_nms():
    rng = np.random.default_rng(3)
    nc, n = 5, 400
    out = clustered_output(rng, nc, n)
    boxes, scores, classes = decode_yolo(out, conf_threshold=0.3, iou_threshold=0.5)
    ref = _reference_decode(out, 0.3, 0.5)
    assert len(ref) > 20 and len(ref) < (out[0, 4:].max(axis=0) > 0.3).sum()  # NMS removed some
    assert len(boxes) == len(ref)
    np.testing.assert_allclose(scores, [s for s, _, _ in ref], rtol=1e-6)
    np.testing.assert_allclose(boxes, [b for _, b, _ in ref], atol=1e-3)
    np.testing.assert_array_equal(classes, [c for _, _, c in ref])


def test_decode_rejects_wrong_shapes():
    for shape in [(1, 4, 10), (2, 9, 10), (9, 10)]:
        with pytest.raises(ValueError, match=r"\(1, 4 \+ nc, N\)"):
            decode_yolo(np.zeros(shape, np.float32))
    b, s, c = decode_yolo(np.zeros((1, 6, 10), np.float32))
    assert b.shape == (0, 4) and s.shape == (0,) and c.shape == (0,)


def _save_model(path, nodes, inits, in_size, out_shape):
    x = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, in_size, in_size])
    y = helper.make_tensor_value_info("output0", TensorProto.FLOAT, list(out_shape))
    g = helper.make_graph(nodes, "tiny_yolo", [x], [y], inits)
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)])
    m.ir_version = 8
    onnx.checker.check_model(m)
    onnx.save(m, str(path))
    return path


IN = 64   # the tiny model's input size
NC = 3


def _yolo_like_model(path, const: np.ndarray, probe_entry: tuple | None):
    """Output = const + mean(input) · e, where e is one-hot at index ``probe_entry`` (or zero):
    e.g. a YOLO-shaped (1, 4 + nc, N) output with one score that depends on the input pixels."""
    onehot = np.zeros_like(const)
    if probe_entry is not None:
        onehot[probe_entry] = 1.0
    nodes = [helper.make_node("ReduceMean", ["images"], ["m"], keepdims=1),
             helper.make_node("Reshape", ["m", "shape3"], ["m3"]),
             helper.make_node("Mul", ["m3", "onehot"], ["probe"]),
             helper.make_node("Add", ["probe", "const"], ["output0"])]
    inits = [numpy_helper.from_array(const, "const"), numpy_helper.from_array(onehot, "onehot"),
             numpy_helper.from_array(np.ones(const.ndim, np.int64), "shape3")]
    return _save_model(path, nodes, inits, IN, const.shape)


def _column(cx, cy, w, h, cls, score):
    col = np.zeros(4 + NC, np.float32)
    col[:4] = cx, cy, w, h
    col[4 + cls] = score
    return col


@pytest.fixture()
def tiny_model(tmp_path):
    cols = [
        _column(20, 20, 10, 10, 0, 0.9),   # A: kept
        _column(21, 20, 10, 10, 0, 0.8),   # same class, IoU 0.82 with A: suppressed
        _column(21, 21, 10, 10, 1, 0.7),   # overlaps A but another class: kept (class-wise NMS)
        _column(45, 40, 8, 12, 2, 0.6),    # kept
        _column(45, 20, 8, 8, 1, 0.2),     # below the threshold
        _column(10, 40, 6, 6, 2, 0.0),     # its score is mean(input): the probe
    ]
    const = np.stack(cols, axis=1)[None].astype(np.float32)
    return _yolo_like_model(tmp_path / "tiny.onnx", const, (0, 4 + 2, 5)), const


def test_yolo_detector_letterboxes_decodes_and_maps_classes(tiny_model):
    path, const = tiny_model
    det = YoloOnnxDetector(path, {0: 100, "c1": 101, 2: 102}, ["c0", "c1", "c2"], input_size=IN,
                           conf_threshold=0.25, iou_threshold=0.5)
    assert det.num_classes == NC
    h, w = 240, 320                      # letterbox to 64: scale 0.2, image 64x48, 8 px pad top and bottom
    scale, pad = IN / w, (0.0, (IN - h * IN / w) / 2)
    black = np.zeros((h, w, 3), np.uint8)
    found = det.detect(black)
    # the probe's score is the blob mean: black image area 0, padding 114/255
    probe_score = (2 * 8 * IN * 114 / 255) / (IN * IN)
    assert probe_score < 0.25
    expect = [(0.9, 0, 100), (0.7, 1, 101), (0.6, 2, 102)]
    assert [(round(d.score, 6), d.class_id, d.landmark_id) for d in found] == [(s, c, lid) for s, c, lid in expect]
    for d, j in zip(found, [0, 2, 3]):
        cx, cy, bw, bh = const[0, :4, j]
        want = [(cx - bw / 2 - pad[0]) / scale, (cy - bh / 2 - pad[1]) / scale,
                (cx + bw / 2 - pad[0]) / scale, (cy + bh / 2 - pad[1]) / scale]
        np.testing.assert_allclose(d.box, want, atol=1e-3)
        assert d.class_name == f"c{d.class_id}"
    # a white image lifts the probe above the threshold: the input reaches the network, normalised to [0, 1]
    white = np.full((h, w, 3), 255, np.uint8)
    found = det.detect(white)
    probe = [d for d in found if d.class_id == 2 and abs(d.score - 0.6) > 1e-6]
    want_score = (48 * IN * 1.0 + 2 * 8 * IN * 114 / 255) / (IN * IN)
    assert len(probe) == 1 and probe[0].score == pytest.approx(want_score, abs=1e-4)
    cx, cy, bw, bh = const[0, :4, 5]
    np.testing.assert_allclose(probe[0].box, [(cx - bw / 2) / scale, (cy - bh / 2 - pad[1]) / scale,
                                              (cx + bw / 2) / scale, (cy + bh / 2 - pad[1]) / scale], atol=1e-3)


def test_yolo_unmapped_classes_are_skipped_or_raise(tiny_model):
    path, _ = tiny_model
    img = np.zeros((64, 64, 3), np.uint8)
    det = YoloOnnxDetector(path, {0: 5}, input_size=IN)
    assert [d.landmark_id for d in det.detect(img)] == [5]
    strict = YoloOnnxDetector(path, {0: 5}, input_size=IN, unknown="error")
    with pytest.raises(ValueError, match="class 1"):
        strict.detect(img)


def test_yolo_model_errors_name_the_path_and_value(tmp_path, tiny_model):
    path, _ = tiny_model
    missing = tmp_path / "nope" / "best.onnx"
    with pytest.raises(FileNotFoundError, match="best.onnx"):
        YoloOnnxDetector(missing, {0: 1})
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"this is not a protobuf" * 10)
    with pytest.raises(ValueError, match="garbage.onnx"):
        YoloOnnxDetector(garbage, {0: 1}, input_size=IN)
    # a classifier-shaped output (1, nc) and a (1, 4, N) output with no class rows are incompatible
    for name, shape in (("classifier.onnx", (1, 10)), ("noclass.onnx", (1, 4, 6))):
        bad = _yolo_like_model(tmp_path / name, np.zeros(shape, np.float32), None)
        with pytest.raises(ValueError, match=rf"{name}.*output shape \({', '.join(map(str, shape))}"):
            YoloOnnxDetector(bad, {0: 1}, input_size=IN)
    with pytest.raises(ValueError, match="'tank'"):
        YoloOnnxDetector(path, {"tank": 1}, ["c0", "c1", "c2"], input_size=IN)
    with pytest.raises(ValueError, match="unknown class 7"):
        YoloOnnxDetector(path, {7: 1}, input_size=IN)
    with pytest.raises(ValueError, match="2 names"):
        YoloOnnxDetector(path, {0: 1}, ["a", "b"], input_size=IN)
    det = YoloOnnxDetector(path, {0: 1}, input_size=IN)
    with pytest.raises(ValueError, match="empty"):
        det.detect(np.zeros((0, 5, 3), np.uint8))


def test_letterbox_geometry():
    img = np.full((240, 320, 3), 7, np.uint8)
    out, scale, pad = letterbox(img, 64)
    assert out.shape == (64, 64, 3) and scale == (0.2, 0.2) and pad == (0, 8)
    assert (out[:8] == 114).all() and (out[56:] == 114).all() and (out[8:56] == 7).all()
    assert aruco_dictionary("apriltag_36h11").markerSize == 6
    assert isinstance(Detection(1, "x", (0, 0, 2, 4), 1.0).center, tuple)
