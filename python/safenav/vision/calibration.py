"""Stereo calibration for LanBLoc's ranging [SafeNav §IV-A]:
:class:`StereoCalibration` — ``K1, D1, K2, D2, R, T`` and the image size,
exactly what ``cv2.stereoCalibrate`` returns (``X₂ = R X₁ + T``); loads and
saves OpenCV FileStorage YAML/XML (also OpenCV's ``stereo_calib`` sample
files with ``M1``/``M2`` in one file and ``R``/``T`` in another).  Validated
by the core (``ValueError`` naming the field)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import _core

__all__ = ["StereoCalibration"]


def _image_size(value) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in value)
        ok = all(float(v) == int(v) for v in value)
    except (TypeError, ValueError):
        ok = False
    if not ok or w <= 0 or h <= 0:
        raise ValueError(f"image_size must be (width, height) positive integers, got {value!r}")
    return w, h


def _distortion(name, value) -> np.ndarray:
    d = np.asarray(value, dtype=np.float64).ravel() if value is not None else np.zeros(0)
    if d.size not in (0, 4, 5, 8, 12, 14):
        raise ValueError(f"calibration {name} has {d.size} coefficients; OpenCV takes 0, 4, 5, 8, 12 or 14")
    return np.ascontiguousarray(d)


@dataclass(frozen=True)
class StereoCalibration:
    """A calibrated stereo rig (what ``cv2.stereoCalibrate`` returns).

    ``K1``, ``K2`` are 3×3 intrinsics, ``D1``, ``D2`` distortion vectors
    (0/4/5/8/12/14 coefficients), ``R`` (3×3) and ``T`` (3,) the pose of
    camera 2 in camera 1's frame (``X₂ = R X₁ + T``; ``T[0] < 0`` when camera
    2 is on the right), ``image_size = (width, height)``.  Validated on
    construction: a NaN anywhere raises ``ValueError`` naming the field.
    """

    K1: np.ndarray
    D1: np.ndarray
    K2: np.ndarray
    D2: np.ndarray
    R: np.ndarray
    T: np.ndarray
    image_size: tuple[int, int]

    def __post_init__(self):
        for name in ("K1", "K2", "R"):
            object.__setattr__(self, name, _matrix(name, getattr(self, name), (3, 3)))
        object.__setattr__(self, "T", _matrix("T", np.asarray(self.T, dtype=np.float64).ravel(), (3,)))
        object.__setattr__(self, "D1", _distortion("D1", self.D1))
        object.__setattr__(self, "D2", _distortion("D2", self.D2))
        object.__setattr__(self, "image_size", _image_size(self.image_size))
        self._core().validate()  # NaN, rotation, baseline, rig orientation → ValueError naming the field

    def _core(self) -> _core.StereoCalibration:
        c = _core.StereoCalibration()
        c.K1, c.D1, c.K2, c.D2, c.R, c.T = self.K1, self.D1, self.K2, self.D2, self.R, self.T
        c.width, c.height = self.image_size
        return c

    @property
    def baseline(self) -> float:
        """‖T‖, in the unit of T."""
        return float(np.linalg.norm(self.T))

    def save(self, path) -> None:
        """Write OpenCV FileStorage (``.yml``/``.yaml``/``.xml``/``.json``, by extension)."""
        import cv2

        path = Path(path)
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        if not fs.isOpened():
            raise ValueError(f"cannot open {str(path)!r} for writing")
        try:
            for name in ("K1", "D1", "K2", "D2", "R"):
                value = getattr(self, name)
                fs.write(name, value.reshape(1, -1) if value.ndim == 1 else value)
            fs.write("T", self.T.reshape(3, 1))
            fs.write("image_width", int(self.image_size[0]))
            fs.write("image_height", int(self.image_size[1]))
        finally:
            fs.release()

    @classmethod
    def load(cls, path, extrinsics_path=None) -> "StereoCalibration":
        """Read OpenCV FileStorage written by :meth:`save` or by OpenCV itself.

        Intrinsics may be named ``K1``/``K2`` or ``M1``/``M2`` (OpenCV's
        ``stereo_calib`` sample, which writes ``intrinsics.yml`` and, with
        ``R``/``T``, ``extrinsics.yml``: pass that as ``extrinsics_path``).
        The image size is ``image_width``/``image_height``, ``image_size`` or
        ``imageSize`` (``[width, height]``).  Missing nodes raise ``ValueError``
        naming the node and the file.
        """
        import cv2

        nodes = {}
        for p in (path,) + ((extrinsics_path,) if extrinsics_path is not None else ()):
            p = Path(p)
            if not p.is_file():
                raise ValueError(f"calibration file {str(p)!r} does not exist")
            try:
                fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
            except (cv2.error, SystemError) as exc:  # cv2 raises SystemError on unparsable files
                raise ValueError(f"calibration file {str(p)!r} is not OpenCV FileStorage: {exc}") from exc
            if not fs.isOpened():
                raise ValueError(f"calibration file {str(p)!r} is not OpenCV FileStorage")
            try:
                root = fs.root()
                for key in root.keys():
                    nodes[key] = (_read(root.getNode(key)), p)
            finally:
                fs.release()

        def get(*names, required=True):
            for n in names:
                if n in nodes and nodes[n][0] is not None:
                    return nodes[n][0]
            if required:
                raise ValueError(f"calibration file {str(path)!r} has no {' / '.join(names)} node")
            return None

        mats = dict(K1=get("K1", "M1"), D1=get("D1"), K2=get("K2", "M2"), D2=get("D2"), R=get("R"), T=get("T"))
        if get("image_width", required=False) is not None:
            size = (get("image_width"), get("image_height"))
        else:
            size = np.asarray(get("image_size", "imageSize")).ravel()
        return cls(**mats, image_size=tuple(size))


def _read(node):
    if node.isNone():
        return None
    if node.isInt() or node.isReal():
        return node.real()
    if node.isSeq():
        return np.array([node.at(i).real() for i in range(node.size())], dtype=np.float64)
    m = node.mat()
    if m is None:
        # an empty matrix (e.g. no distortion coefficients) reads back as None: keep it as empty
        if node.isMap() and not node.getNode("rows").isNone() and not node.getNode("cols").isNone() \
                and int(node.getNode("rows").real()) * int(node.getNode("cols").real()) == 0:
            return np.zeros(0)
        return None
    return np.asarray(m, dtype=np.float64)


def _matrix(name, value, shape):
    try:
        arr = np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"calibration {name} must be numeric, got {value!r}") from exc
    if arr.shape != shape:
        raise ValueError(f"calibration {name} must have shape {shape}, got {arr.shape}")
    return arr  # finiteness is checked in C++ with the entry named
