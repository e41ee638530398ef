"""Rendering by region (ours): :class:`StereoFrame`, the rectified stereo pair
at one pose drawn region by region on demand (see "Rendering by region" in
:mod:`safenav.vision.render`).  A frame is made by
:meth:`safenav.vision.render.StereoRenderer.frame` and draws its pixels with
that renderer's textures, markers and noise."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from .rig import as_pose, camera_rotation

if TYPE_CHECKING:
    from .render import StereoRenderer

__all__ = ["StereoFrame"]


@dataclass(frozen=True)
class _Drawn:
    depth: float            # mean camera depth of the board's corners [m] (painter's order)
    landmark_id: int
    uv: np.ndarray          # (4, 2) board corners, level-0 pixels (TL, TR, BR, BL)
    pole: np.ndarray | None  # (4, 2) pole quad, level-0 pixels
    box: tuple[int, int, int, int]   # level-0 pixel box x0, y0, x1, y1 (ends exclusive), clipped to the image
    min_side: float         # shortest / longest board side, level-0 pixels
    max_side: float
    whole: bool             # the marker's four corners (inside the quiet zone) lie in the image


def _intersects(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


class StereoFrame:
    """The rectified stereo pair at one pose, drawn region by region on demand
    (see "Rendering by region" in :mod:`safenav.vision.render`).  Made by
    :meth:`~safenav.vision.render.StereoRenderer.frame`; the markers' geometry
    is computed once, the pixels only when :meth:`patch` asks for them."""

    CAMERAS = ("left", "right")

    def __init__(self, renderer: StereoRenderer, pose, noise_seed: int | None = None, images=None):
        self.renderer = renderer
        #: ``(left, right)`` full-resolution grey images that :meth:`patch` cuts from instead of
        #: drawing (e.g. a pair already rendered, to run the region pipeline on the same pixels as
        #: another detector); ``None``: drawn on demand
        self.images = None if images is None else self._checked_images(renderer.rig, images)
        self._rng = renderer._rng if noise_seed is None else np.random.default_rng(noise_seed)
        self._offsets, self._next = None, 0   # noise-tile offsets, drawn 32 at a time
        r = self.rig = renderer.rig
        x, y, th = as_pose(pose)
        self.pose = (x, y, th)
        #: the background's horizontal offset: it slides f px per radian of heading, like one at infinity
        self._bg_shift = int(round(-th * r.focal_length_px))
        self._drawn: dict[str, list[_Drawn]] = {cam: [] for cam in self.CAMERAS}
        idx = renderer.culled(self.pose)
        if len(idx) == 0:
            return
        boards = self._boards(renderer, idx)
        hidden = renderer.hidden(self.pose)
        ids = [renderer.landmarks[i].id for i in idx]
        for cam, C in zip(self.CAMERAS, r.camera_centers(self.pose)):
            self._drawn[cam] = [d for d in self._projected(boards, C, ids) if d.landmark_id not in hidden[cam]]

    @classmethod
    def _checked_images(cls, rig, images) -> tuple:
        """``images`` as a pair of contiguous uint8 arrays of the rig's size, or a ValueError naming the bad one."""
        try:
            left, right = images
        except (TypeError, ValueError):
            raise ValueError(f"images = {images!r}: must be a pair (left, right)") from None
        ims = tuple(np.ascontiguousarray(a) for a in (left, right))
        for name, a in zip(cls.CAMERAS, ims):
            if a.dtype != np.uint8 or a.shape != (rig.height, rig.width):
                raise ValueError(f"images: the {name} image is {a.dtype} {a.shape}, expected uint8 "
                                 f"({rig.height}, {rig.width})")
        return ims

    def _boards(self, renderer, idx) -> dict:
        """Every culled board at once (as StereoRenderer._board): whether it faces the camera, its
        corners and its pole's, in the world (n, 4, 3), and its bottom edge's height; and the
        cameras' rotation at the pose."""
        x, y, th = self.pose
        r = self.rig
        c = renderer._L[idx]
        if renderer._yaw is None:
            mid = np.array([x, y]) + 0.5 * r.baseline_m * np.array([math.sin(th), -math.cos(th)])
            n = mid - c[:, :2]
            nn = np.hypot(n[:, 0], n[:, 1])
            far = nn > 1e-9
            n[far] /= nn[far, None]
            n[~far] = (-math.cos(th), -math.sin(th))
        else:
            yaw = renderer._yaw[idx]
            n = np.column_stack([np.cos(yaw), np.sin(yaw)])
        facing = (n * (np.array([x, y]) - c[:, :2])).sum(axis=1) > 0
        a = np.column_stack([-n[:, 1], n[:, 0], np.zeros(len(idx))])
        up = np.array([0.0, 0.0, 1.0])
        hb = renderer._board_half_m
        sa, su = np.array([-1.0, 1.0, 1.0, -1.0]), np.array([1.0, 1.0, -1.0, -1.0])
        corners = c[:, None, :] + hb * (sa[None, :, None] * a[:, None, :] + su[None, :, None] * up)
        pw = 0.5 * renderer.POLE_WIDTH_M
        bottom = c[:, 2] - hb
        pole = np.stack([c + (bottom - c[:, 2])[:, None] * up - pw * a, c + (bottom - c[:, 2])[:, None] * up + pw * a,
                         c - c[:, 2:3] * up + pw * a, c - c[:, 2:3] * up - pw * a], axis=1)
        cells = renderer.dictionary.markerSize + 2
        return dict(facing=facing, corners=corners, pole=pole, bottom=bottom, inner=cells / (cells + 2),
                    R=camera_rotation(th, r.pitch_rad))

    def _projected(self, boards: dict, C, ids) -> list[_Drawn]:
        """The boards as the camera at centre ``C`` sees them, far first (painter's order)."""
        r = self.rig
        R = boards["R"]
        f, cx, cy = r.focal_length_px, r.cx, r.cy
        pc = (boards["corners"] - C) @ R.T                       # (n, 4, 3)
        pp = (boards["pole"] - C) @ R.T
        ok = boards["facing"] & (pc[:, :, 2] > r.near_m).all(axis=1)
        if not ok.any():
            return []
        uv = f * pc[:, :, :2] / np.where(ok[:, None, None], pc[:, :, 2:3], 1.0) + [cx, cy]
        pole_ok = (boards["bottom"] > 0) & (pp[:, :, 2] > r.near_m).all(axis=1)
        puv = f * pp[:, :, :2] / np.where(pole_ok[:, None, None], pp[:, :, 2:3], 1.0) + [cx, cy]
        lo = np.floor(uv.min(axis=1)) - 1
        hi = np.ceil(uv.max(axis=1)) + 2
        side = np.linalg.norm(uv - np.roll(uv, 1, axis=1), axis=2)
        depth = pc[:, :, 2].mean(axis=1)
        # the marker inside the quiet zone (marker side / board side): a detector needs its four corners in the image
        mc = pc.mean(axis=1, keepdims=True)
        pm = mc + boards["inner"] * (pc - mc)
        um = f * pm[:, :, :2] / np.where(ok[:, None, None], pm[:, :, 2:3], 1.0) + [cx, cy]
        whole = ((um >= 0).all(axis=2) & (um[:, :, 0] <= r.width - 1) & (um[:, :, 1] <= r.height - 1)).all(axis=1)
        items = []
        for k in np.flatnonzero(ok):
            box = (int(max(lo[k, 0], 0)), int(max(lo[k, 1], 0)), int(min(hi[k, 0], r.width)),
                   int(min(hi[k, 1], r.height)))
            if box[2] <= box[0] or box[3] <= box[1]:
                continue
            items.append(_Drawn(float(depth[k]), ids[k], uv[k], puv[k] if pole_ok[k] else None, box,
                                float(side[k].min()), float(side[k].max()), bool(whole[k])))
        items.sort(key=lambda t: -t.depth)   # far first
        return items

    def _camera(self, camera: str) -> list[_Drawn]:
        if camera not in self.CAMERAS:
            raise ValueError(f"camera = {camera!r}: must be 'left' or 'right'")
        return self._drawn[camera]

    def whole_markers(self, camera: str = "left") -> list[int]:
        """Ids of the markers drawn in ``camera`` with all four corners inside the image: the most a
        detector can find (one cut by the image's edge has no fourth corner)."""
        return [d.landmark_id for d in self._camera(camera) if d.whole]

    def footprints(self, camera: str = "left") -> dict[int, tuple[int, int, int, int]]:
        """``landmark id → level-0 pixel box (x0, y0, x1, y1)`` of every marker board drawn in ``camera``."""
        return {d.landmark_id: d.box for d in self._camera(camera)}

    def regions(self, camera: str = "left", margin_px: int = 8) -> list[tuple[tuple[int, int, int, int], float]]:
        """The image regions that hold markers: the footprints grown by ``margin_px`` (clipped to the
        image) and merged where they overlap, each with the smallest board side in it [px]."""
        if isinstance(margin_px, bool) or not isinstance(margin_px, (int, np.integer)) or margin_px < 0:
            raise ValueError(f"margin_px = {margin_px!r}: must be an integer >= 0")
        w, h = self.rig.width, self.rig.height
        boxes = []
        for d in self._camera(camera):
            x0, y0, x1, y1 = d.box
            boxes.append([max(x0 - margin_px, 0), max(y0 - margin_px, 0), min(x1 + margin_px, w),
                          min(y1 + margin_px, h), d.min_side])
        merged = True
        while merged:
            merged = False
            for i in range(len(boxes)):
                for j in range(i + 1, len(boxes)):
                    a, b = boxes[i], boxes[j]
                    if _intersects(a, b):
                        boxes[i] = [min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]), min(a[4], b[4])]
                        del boxes[j]
                        merged = True
                        break
                if merged:
                    break
        return [((int(b[0]), int(b[1]), int(b[2]), int(b[3])), b[4]) for b in boxes]

    def patch(self, camera: str, box, level: int = 0) -> np.ndarray:
        """The (grey, uint8) pixels of ``camera``'s image in the level-0 box ``(x0, y0, x1, y1)``
        (ends exclusive), at pyramid level ``level``: the level-``L`` pixels ``x0 // 2^L ..
        ceil(x1 / 2^L) − 1`` (and rows likewise)."""
        items = self._camera(camera)
        if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or not 0 <= level <= 8:
            raise ValueError(f"level = {level!r}: must be an integer in [0, 8]")
        try:
            x0, y0, x1, y1 = (int(v) for v in box)
        except (TypeError, ValueError):
            raise ValueError(f"box = {box!r}: must be four integers (x0, y0, x1, y1)") from None
        if not (0 <= x0 < x1 <= self.rig.width and 0 <= y0 < y1 <= self.rig.height):
            raise ValueError(f"box = {tuple(box)}: must lie inside the {self.rig.width}x{self.rig.height} image "
                             f"with x0 < x1, y0 < y1")
        k = 1 << int(level)
        X0, Y0, X1, Y1 = x0 // k, y0 // k, -(-x1 // k), -(-y1 // k)
        if self.images is not None:
            return self._cut(camera, X0, Y0, X1, Y1, k)
        img = self.renderer._background_patch(int(level), X0, Y0, X1, Y1, self._bg_shift // k)
        off = np.array([X0, Y0], float)
        lbox = (X0 * k, Y0 * k, X1 * k, Y1 * k)
        for d in items:
            if not _intersects(d.box, lbox):
                continue
            if d.pole is not None:
                cv2.fillConvexPoly(img, np.round(((d.pole + 0.5) / k - 0.5 - off) * 16).astype(np.int32), 70,
                                   cv2.LINE_AA, 4)
            self.renderer._warp_marker(img, d.landmark_id, (d.uv + 0.5) / k - 0.5 - off, d.max_side / k)
        if self.renderer.noise_std > 0:
            if self._offsets is None or self._next >= len(self._offsets):
                self._offsets = self._rng.integers(0, self.renderer.NOISE_TILE, (32, 2)).tolist()
                self._next = 0
            self._next += 1
            noise = self.renderer._noise(img.shape, self.renderer.noise_std / k, self._rng, self._offsets[self._next - 1])
            img = np.clip(img + noise + 0.5, 0, 255).astype(np.uint8)
        return img

    def _cut(self, camera: str, X0: int, Y0: int, X1: int, Y1: int, k: int) -> np.ndarray:
        """Level pixels [X0, X1) × [Y0, Y1) (2^L = ``k``) of the given image: the k×k block means
        (``cv2.INTER_AREA``), the blocks past the image's edge filled by repeating its edge pixels."""
        img = self.images[self.CAMERAS.index(camera)]
        h, w = img.shape
        block = img[Y0 * k:min(Y1 * k, h), X0 * k:min(X1 * k, w)]
        if k == 1:
            return block.copy()
        pad_y, pad_x = Y1 * k - (Y0 * k + block.shape[0]), X1 * k - (X0 * k + block.shape[1])
        if pad_x or pad_y:
            block = cv2.copyMakeBorder(block, 0, pad_y, 0, pad_x, cv2.BORDER_REPLICATE)
        return cv2.resize(block, (X1 - X0, Y1 - Y0), interpolation=cv2.INTER_AREA)
