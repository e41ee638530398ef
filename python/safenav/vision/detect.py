"""Landmark recognition for LanBLoc [SafeNav §IV-A].

The paper recognises landmarks with a YOLOv11s model trained on
MSTLandmarkv1 (34 classes); the recognised landmark's box then selects the
disparity pixels whose median gives its distance.  Two detectors share one
interface, :class:`Detector`, whose :meth:`~Detector.detect` returns a list of
:class:`Detection` (landmark id, class name, box ``(x0, y0, x1, y1)`` in
pixels, score):

* :class:`FiducialDetector` — the default.  ArUco or AprilTag markers through
  ``cv2.aruco``; it needs no model file.  A marker id becomes a landmark id
  through the landmark map (identity by default; a :class:`~safenav.world.World`
  gives the identity restricted to its landmarks, with their class names).
* :class:`YoloOnnxDetector` — a YOLOv8/YOLO11 detection model exported to
  ONNX by the user (``yolo export format=onnx``), run through ``cv2.dnn``.
  Letterbox preprocessing, decoding of the ``(1, 4 + nc, N)`` output
  (rows ``cx, cy, w, h`` then one sigmoid score per class), a confidence
  threshold, class-wise NMS (``cv2.dnn.NMSBoxesBatched``), and class → landmark
  id through the landmark map.

Errors name the bad value: a missing model file (``FileNotFoundError`` with
the path), a file OpenCV cannot read or whose output is not shaped like
YOLO's (``ValueError`` with the path and the shape), a landmark map naming a
class the model does not have (``ValueError`` with the class).
"""

from __future__ import annotations

import math
import os
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import cv2
import numpy as np

__all__ = [
    "Detection", "Detector", "FiducialDetector", "YoloOnnxDetector", "aruco_dictionary",
    "marker_image", "letterbox", "decode_yolo", "as_gray", "check_image",
]


# --------------------------------------------------------------------------- result type

@dataclass(frozen=True)
class Detection:
    """One recognised landmark.

    ``box`` is ``(x0, y0, x1, y1)`` in pixels of the input image (x right,
    y down, edges inclusive of the object's extent); ``corners`` holds the
    four marker corners ``(4, 2)`` for fiducials (top-left first, clockwise)
    and is ``None`` for YOLO boxes.
    """

    landmark_id: int
    class_name: str
    box: tuple[float, float, float, float]
    score: float
    class_id: int = -1
    corners: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def center(self) -> tuple[float, float]:
        """Box centre (u, v) in pixels."""
        x0, y0, x1, y1 = self.box
        return 0.5 * (x0 + x1), 0.5 * (y0 + y1)

    @property
    def width(self) -> float:
        return self.box[2] - self.box[0]

    @property
    def height(self) -> float:
        return self.box[3] - self.box[1]


# --------------------------------------------------------------------------- helpers

def as_gray(image, name: str = "image") -> np.ndarray:
    """``image`` (H, W) or (H, W, 3|4) uint8 as a (H, W) uint8 grey image; errors name ``name``."""
    img = check_image(image, name)
    if img.ndim == 2:
        return img
    code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
    return cv2.cvtColor(img, code)


def check_image(image, name: str) -> np.ndarray:
    """``image`` as a (H, W) or (H, W, 3|4) uint8 array ((H, W, 1) loses its last
    axis); ``ValueError`` naming ``name`` otherwise."""
    if image is None:
        raise ValueError(f"{name} is None, expected an image array")
    img = np.asarray(image)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3, 4)):
        raise ValueError(f"{name} must have shape (H, W) or (H, W, 1|3|4), got {img.shape}")
    if img.size == 0 or img.shape[0] == 0 or img.shape[1] == 0:
        raise ValueError(f"{name} is empty (shape {img.shape})")
    if img.dtype != np.uint8:
        raise ValueError(f"{name} must be uint8, got dtype {img.dtype}")
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    return img


_DICT_ALIASES = {"APRILTAG_16H5": "APRILTAG_16h5", "APRILTAG_25H9": "APRILTAG_25h9",
                 "APRILTAG_36H10": "APRILTAG_36h10", "APRILTAG_36H11": "APRILTAG_36h11"}


def aruco_dictionary(name: str | int = "DICT_4X4_100") -> cv2.aruco.Dictionary:
    """The predefined ``cv2.aruco`` dictionary ``name`` (``"DICT_4X4_100"``, ``"APRILTAG_36h11"``, …)."""
    if isinstance(name, cv2.aruco.Dictionary):
        return name
    if isinstance(name, (int, np.integer)) and not isinstance(name, bool):
        return cv2.aruco.getPredefinedDictionary(int(name))
    if not isinstance(name, str):
        raise ValueError(f"dictionary = {name!r}: must be a cv2.aruco dictionary name such as 'DICT_4X4_100'")
    key = name.upper()
    key = key if key.startswith("DICT_") else "DICT_" + key
    if not hasattr(cv2.aruco, key):
        known = sorted(k[5:] for k in dir(cv2.aruco) if k.startswith("DICT_"))
        raise ValueError(f"dictionary = {name!r}: unknown; known: {', '.join(known)}")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, key))


def _dictionary_size(d: cv2.aruco.Dictionary) -> int:
    return int(d.bytesList.shape[0])


def marker_image(dictionary, marker_id: int, cell_px: int = 8, border_cells: int = 1) -> np.ndarray:
    """The marker ``marker_id`` of ``dictionary`` as a uint8 image with a white quiet zone.

    The black-framed marker has ``markerSize + 2`` cells per side; a white
    border of ``border_cells`` cells is added on every side, so the image is
    ``(markerSize + 2 + 2·border_cells)·cell_px`` pixels square.
    """
    d = aruco_dictionary(dictionary)
    n = _dictionary_size(d)
    if isinstance(marker_id, bool) or not isinstance(marker_id, (int, np.integer)) or not 0 <= marker_id < n:
        raise ValueError(f"marker_id = {marker_id!r}: must be an integer in [0, {n}) for this dictionary")
    if cell_px < 1 or border_cells < 0:
        raise ValueError(f"cell_px = {cell_px!r}, border_cells = {border_cells!r}: need cell_px >= 1, border_cells >= 0")
    cells = d.markerSize + 2
    img = cv2.aruco.generateImageMarker(d, int(marker_id), cells * cell_px)
    b = border_cells * cell_px
    return cv2.copyMakeBorder(img, b, b, b, b, cv2.BORDER_CONSTANT, value=255)


def _landmark_table(landmark_map) -> tuple[dict[int, int], dict[int, str]]:
    """``(marker id → landmark id, landmark id → class name)`` from a mapping or a World."""
    from ..world import World
    if isinstance(landmark_map, World):
        return ({lm.id: lm.id for lm in landmark_map.landmarks},
                {lm.id: lm.class_name for lm in landmark_map.landmarks})
    if not isinstance(landmark_map, Mapping):
        raise ValueError(f"landmark_map = {landmark_map!r}: must be a mapping marker id -> landmark id or a World")
    table = {}
    for k, v in landmark_map.items():
        for what, x in (("marker id", k), ("landmark id", v)):
            if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x < 0:
                raise ValueError(f"landmark_map[{k!r}] = {v!r}: {what} {x!r} must be a non-negative integer")
        table[int(k)] = int(v)
    return table, {}


# --------------------------------------------------------------------------- interface

class Detector(ABC):
    """Finds landmarks in one image.  ``detect(image)`` → list of :class:`Detection`."""

    name: str = "detector"

    @abstractmethod
    def detect(self, image) -> list[Detection]:
        """Detections in ``image`` ((H, W) grey or (H, W, 3) BGR uint8), best score first."""

    def __call__(self, image) -> list[Detection]:
        return self.detect(image)


# --------------------------------------------------------------------------- fiducials

class FiducialDetector(Detector):
    """ArUco/AprilTag markers as landmarks (``cv2.aruco.ArucoDetector``); no model file.

    Parameters
    ----------
    landmark_map:
        ``None`` (marker id = landmark id), a mapping ``marker id → landmark
        id``, or a :class:`~safenav.world.World` (identity on its landmark ids,
        class names from the world).  Markers missing from the map are not
        landmarks and are skipped (their ids are kept in :attr:`last_unmapped`).
    dictionary:
        A ``cv2.aruco`` dictionary name, e.g. ``"DICT_4X4_100"`` (default) or
        ``"APRILTAG_36h11"``.
    subpixel:
        Refine the corners to sub-pixel accuracy (``CORNER_REFINE_SUBPIX``).
    min_perimeter_rate:
        ArUco's ``minMarkerPerimeterRate`` (perimeter relative to the larger
        image side); the default admits markers of about 4 px per side.
    error_correction_rate, max_border_error_rate:
        ArUco's ``errorCorrectionRate`` and ``maxErroneousBitsInBorderRate``,
        tighter than OpenCV's 0.6 and 0.35: on rendered ground texture the
        defaults read one false marker in 339 frames of the default
        scenario's paths, these none, for one missed marker in 870.
    aruco3:
        ArUco 3's faster candidate search (``useAruco3Detection``); the
        camera loop's region mode uses it (its regions hold one or a few
        markers that fill them).

    The score of a fiducial is 1.
    """

    name = "fiducial"

    def __init__(self, landmark_map=None, dictionary: str = "DICT_4X4_100", *, subpixel: bool = True,
                 min_perimeter_rate: float = 0.02, error_correction_rate: float = 0.3,
                 max_border_error_rate: float = 0.1, aruco3: bool = False):
        self.dictionary = aruco_dictionary(dictionary)
        self.dictionary_name = dictionary if isinstance(dictionary, str) else repr(dictionary)
        self._map, self._names = (None, {}) if landmark_map is None else _landmark_table(landmark_map)
        n = _dictionary_size(self.dictionary)
        if self._map is not None:
            for m in self._map:
                if m >= n:
                    raise ValueError(f"landmark_map: marker id {m} is not in dictionary {self.dictionary_name} "
                                     f"(ids 0..{n - 1})")
        if not (math.isfinite(min_perimeter_rate) and 0 < min_perimeter_rate < 4):
            raise ValueError(f"min_perimeter_rate = {min_perimeter_rate!r}: must be in (0, 4)")
        for n, v in (("error_correction_rate", error_correction_rate), ("max_border_error_rate", max_border_error_rate)):
            if not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
                raise ValueError(f"{n} = {v!r}: must be in [0, 1]")
        params = cv2.aruco.DetectorParameters()
        params.minMarkerPerimeterRate = float(min_perimeter_rate)
        params.errorCorrectionRate = float(error_correction_rate)
        params.maxErroneousBitsInBorderRate = float(max_border_error_rate)
        if subpixel:
            params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
            params.cornerRefinementWinSize = 3
        # ArUco 3 (Romero-Ramirez et al. 2018): candidates are filtered before decoding, which on
        # small, marker-filled regions is about 10x faster than the classic search
        params.useAruco3Detection = bool(aruco3)
        self._detector = cv2.aruco.ArucoDetector(self.dictionary, params)
        self._classic = None
        if aruco3:
            classic = cv2.aruco.DetectorParameters()
            for name in ("minMarkerPerimeterRate", "errorCorrectionRate", "maxErroneousBitsInBorderRate",
                         "cornerRefinementMethod", "cornerRefinementWinSize"):
                setattr(classic, name, getattr(params, name))
            self._classic = cv2.aruco.ArucoDetector(self.dictionary, classic)
        self.last_unmapped: list[int] = []

    def detect(self, image) -> list[Detection]:
        gray = as_gray(image)
        try:
            corners, ids, _ = self._detector.detectMarkers(gray)
        except cv2.error:
            if self._classic is None:
                raise
            # ArUco 3's pyramid fails an assertion on some small images (OpenCV 4.7-5.0): the classic search
            corners, ids, _ = self._classic.detectMarkers(gray)
        out, unmapped = [], []
        if ids is None:
            self.last_unmapped = unmapped
            return out
        for c, mid in zip(corners, ids.ravel()):
            mid = int(mid)
            if self._map is None:
                lid = mid
            elif mid in self._map:
                lid = self._map[mid]
            else:
                unmapped.append(mid)
                continue
            pts = np.asarray(c, dtype=np.float64).reshape(4, 2)
            (x0, y0), (x1, y1) = pts.min(axis=0), pts.max(axis=0)
            out.append(Detection(lid, self._names.get(lid, "marker"), (float(x0), float(y0), float(x1), float(y1)),
                                 1.0, mid, pts))
        self.last_unmapped = unmapped
        out.sort(key=lambda d: d.landmark_id)
        return out


# --------------------------------------------------------------------------- YOLO (ONNX)

def letterbox(image: np.ndarray, size: int | tuple[int, int] = 640, color: int = 114):
    """Resize keeping the aspect ratio and pad to ``size`` (Ultralytics' letterbox).

    Returns ``(padded image, (scale_x, scale_y), (pad_x, pad_y))``; a point
    ``p`` of the padded image is ``(p - pad) / scale`` in the original.
    """
    w_out, h_out = (size, size) if isinstance(size, (int, np.integer)) else size
    h, w = image.shape[:2]
    scale = min(w_out / w, h_out / h)
    nw, nh = int(round(w * scale)), int(round(h * scale))
    dw, dh = (w_out - nw) / 2.0, (h_out - nh) / 2.0
    left, top = int(round(dw - 0.1)), int(round(dh - 0.1))
    right, bottom = w_out - nw - left, h_out - nh - top
    interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    resized = image if (nw, nh) == (w, h) else cv2.resize(image, (nw, nh), interpolation=interp)
    fill = (color,) * (3 if resized.ndim == 3 else 1)
    padded = cv2.copyMakeBorder(resized, top, bottom, left, right, cv2.BORDER_CONSTANT, value=fill)
    # the effective per-axis scale after rounding to whole pixels
    return padded, (nw / w, nh / h), (left, top)


def decode_yolo(output: np.ndarray, conf_threshold: float = 0.25, iou_threshold: float = 0.45,
                max_detections: int = 300) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decode a YOLOv8/YOLO11 detection output ``(1, 4 + nc, N)`` and apply class-wise NMS.

    Each of the N columns holds ``cx, cy, w, h`` (input pixels) then ``nc``
    class scores.  A column's class is its best-scoring class; columns whose
    best score is not above ``conf_threshold`` are dropped; then NMS at
    ``iou_threshold`` runs separately per class (``cv2.dnn.NMSBoxesBatched``).

    Returns ``(boxes (K, 4) as x0, y0, x1, y1, scores (K,), class ids (K,))``,
    best score first.
    """
    out = np.asarray(output)
    if out.ndim != 3 or out.shape[0] != 1 or out.shape[1] < 5:
        raise ValueError(f"YOLO output has shape {out.shape}, expected (1, 4 + nc, N) with nc >= 1")
    pred = out[0].astype(np.float32, copy=False)
    scores_all = pred[4:]
    cls = np.argmax(scores_all, axis=0)
    score = scores_all[cls, np.arange(pred.shape[1])]
    keep = np.isfinite(score) & (score > conf_threshold) & np.isfinite(pred[:4]).all(axis=0)
    if not keep.any():
        return np.zeros((0, 4)), np.zeros(0), np.zeros(0, dtype=int)
    cx, cy, w, h = pred[:4, keep]
    score, cls = score[keep], cls[keep]
    xywh = np.stack([cx - w / 2, cy - h / 2, w, h], axis=1)
    if hasattr(cv2.dnn, "NMSBoxesBatched"):
        idx = cv2.dnn.NMSBoxesBatched(xywh.tolist(), score.tolist(), cls.tolist(),
                                      float(conf_threshold), float(iou_threshold))
    else:  # pragma: no cover - OpenCV < 4.7: offset boxes per class, then plain NMS
        off = cls[:, None] * (float(np.max(xywh[:, :2] + xywh[:, 2:])) + 1.0)
        shifted = np.concatenate([xywh[:, :2] + off, xywh[:, 2:]], axis=1)
        idx = cv2.dnn.NMSBoxes(shifted.tolist(), score.tolist(), float(conf_threshold), float(iou_threshold))
    idx = np.asarray(idx, dtype=int).ravel()
    idx = idx[np.argsort(-score[idx], kind="stable")][:max_detections]
    boxes = np.stack([xywh[idx, 0], xywh[idx, 1], xywh[idx, 0] + xywh[idx, 2], xywh[idx, 1] + xywh[idx, 3]], axis=1)
    return boxes.astype(np.float64), score[idx].astype(np.float64), cls[idx].astype(int)


class YoloOnnxDetector(Detector):
    """A user-supplied YOLOv8/YOLO11 ONNX detection model run through ``cv2.dnn``.

    Parameters
    ----------
    model_path:
        The ``.onnx`` file (e.g. from ``yolo export model=best.pt format=onnx``).
        Its single output must be ``(1, 4 + nc, N)``.
    landmark_map:
        ``class → landmark id``; keys are class indices or class names (names
        need ``class_names``).  Classes not in the map are not landmarks: their
        boxes are skipped, or raise ``ValueError`` with ``unknown="error"``.
    class_names:
        Names of the model's ``nc`` classes, in order (default ``class0`` …).
    input_size:
        The square input size the model was exported with (640).
    conf_threshold, iou_threshold:
        Score threshold and class-wise NMS IoU threshold.

    Construction loads the model and runs it once on a blank image to check
    the output shape, so an incompatible model fails here, naming the path.
    """

    name = "yolo-onnx"

    def __init__(self, model_path, landmark_map: Mapping, class_names: Sequence[str] | None = None, *,
                 input_size: int = 640, conf_threshold: float = 0.25, iou_threshold: float = 0.45,
                 unknown: str = "skip"):
        path = os.fspath(model_path)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"YOLO model file not found: {path!r}")
        if isinstance(input_size, bool) or not isinstance(input_size, (int, np.integer)) or input_size < 32:
            raise ValueError(f"input_size = {input_size!r}: must be an integer >= 32")
        for n, v in (("conf_threshold", conf_threshold), ("iou_threshold", iou_threshold)):
            if not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
                raise ValueError(f"{n} = {v!r}: must be in [0, 1]")
        if unknown not in ("skip", "error"):
            raise ValueError(f"unknown = {unknown!r}: must be 'skip' or 'error'")
        self.model_path = path
        self.input_size = int(input_size)
        self.conf_threshold = float(conf_threshold)
        self.iou_threshold = float(iou_threshold)
        self.unknown = unknown
        try:
            self._net = cv2.dnn.readNetFromONNX(path)
        except cv2.error as exc:
            raise ValueError(f"cannot read ONNX model {path!r}: {str(exc).strip().splitlines()[-1]}") from None
        if self._net.empty():
            raise ValueError(f"cannot read ONNX model {path!r}: OpenCV returned an empty network")
        try:
            probe = self._forward(np.full((self.input_size, self.input_size, 3), 114, np.uint8))
        except cv2.error as exc:
            raise ValueError(f"ONNX model {path!r} does not run on a (1, 3, {self.input_size}, {self.input_size}) "
                             f"input: {str(exc).strip().splitlines()[-1]}") from None
        if probe.ndim != 3 or probe.shape[0] != 1 or probe.shape[1] < 5:
            raise ValueError(f"ONNX model {path!r} has output shape {probe.shape}; a YOLOv8/11 detection "
                             f"model gives (1, 4 + nc, N)")
        self.num_classes = int(probe.shape[1] - 4)
        if class_names is None:
            class_names = [f"class{k}" for k in range(self.num_classes)]
        class_names = list(class_names)
        if len(class_names) != self.num_classes:
            raise ValueError(f"class_names has {len(class_names)} names but model {path!r} has "
                             f"{self.num_classes} classes (output shape {probe.shape})")
        self.class_names = class_names
        if not isinstance(landmark_map, Mapping):
            raise ValueError(f"landmark_map = {landmark_map!r}: must be a mapping class -> landmark id")
        self.class_to_landmark: dict[int, int] = {}
        for key, lid in landmark_map.items():
            if isinstance(key, str):
                if key not in class_names:
                    raise ValueError(f"landmark_map: unknown class {key!r} (model classes: {class_names})")
                k = class_names.index(key)
            elif isinstance(key, (int, np.integer)) and not isinstance(key, bool) and 0 <= key < self.num_classes:
                k = int(key)
            else:
                raise ValueError(f"landmark_map: unknown class {key!r} (model {path!r} has classes "
                                 f"0..{self.num_classes - 1})")
            if isinstance(lid, bool) or not isinstance(lid, (int, np.integer)) or lid < 0:
                raise ValueError(f"landmark_map[{key!r}] = {lid!r}: landmark id must be a non-negative integer")
            self.class_to_landmark[k] = int(lid)

    def _forward(self, bgr_square: np.ndarray) -> np.ndarray:
        blob = cv2.dnn.blobFromImage(bgr_square, 1.0 / 255.0, swapRB=True)
        self._net.setInput(blob)
        return np.asarray(self._net.forward())

    def raw_output(self, image) -> tuple[np.ndarray, tuple[float, float], tuple[int, int]]:
        """The network's raw output on the letterboxed ``image``, with the letterbox scale and padding."""
        img = check_image(image, "image")
        if img.ndim == 2:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        elif img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
        padded, scale, pad = letterbox(img, self.input_size)
        return self._forward(padded), scale, pad

    def detect(self, image) -> list[Detection]:
        h, w = np.asarray(image).shape[:2] if image is not None else (0, 0)
        out, (sx, sy), (px, py) = self.raw_output(image)
        boxes, scores, classes = decode_yolo(out, self.conf_threshold, self.iou_threshold)
        dets = []
        for b, s, c in zip(boxes, scores, classes):
            c = int(c)
            if c not in self.class_to_landmark:
                if self.unknown == "error":
                    raise ValueError(f"detected class {c} ({self.class_names[c]!r}) is not in the landmark map")
                continue
            x0 = float(np.clip((b[0] - px) / sx, 0, w))
            x1 = float(np.clip((b[2] - px) / sx, 0, w))
            y0 = float(np.clip((b[1] - py) / sy, 0, h))
            y1 = float(np.clip((b[3] - py) / sy, 0, h))
            dets.append(Detection(self.class_to_landmark[c], self.class_names[c], (x0, y0, x1, y1), float(s), c))
        return dets
