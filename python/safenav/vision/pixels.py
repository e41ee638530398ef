"""A stereo frame drawn on demand for the core's front end (ours).

The core's LanBLoc front end reads a frame through ``StereoPixels``: it asks for the
boxes it searches, at the pyramid level it searches them, and for full-resolution
patches around the marker corners it found there (``LanBLocFrontEnd.localize_pixels``,
``Localizer.observe_frame``, ``Navigator.run_frames``).  :class:`FramePixels` answers
from a :class:`~safenav.vision.render.StereoRenderer` at the true pose: each box is
drawn at its level (:meth:`~safenav.vision.render.StereoRenderer.draw_level`: ground,
background, markers, poles and pixel noise, as the whole image has them there), so a
frame costs what the detector reads, not the image's 3.7 million pixels.
"""

from __future__ import annotations

import time

import numpy as np

from .rig import as_pose, camera_rotation

__all__ = ["FramePixels"]


class FramePixels:
    """The rectified pair of ``renderer`` at ``pose``, drawn box by box as the front end asks
    (the core's ``StereoPixels``: :meth:`draw`).  The boards' geometry (culling, occlusion, their
    projection and the pixels each can touch) is computed once; the pixel noise of the boxes comes from the stream ``noise_seed`` in the
    order they are drawn.  ``stats`` (a dict, shared if given) counts ``draws``, ``pixels``
    and ``draw_s``."""

    def __init__(self, renderer, pose, noise_seed: int = 0, stats: dict | None = None):
        x, y, th = as_pose(pose)
        self.renderer, self.pose = renderer, (x, y, th)
        r = renderer.rig
        self._R = camera_rotation(th, r.pitch_rad)
        self._centres = r.camera_centers(self.pose)
        idx = renderer.culled(self.pose)
        boards = [renderer._board(i, self.pose) for i in idx]
        hidden = renderer.hidden(self.pose) if len(idx) else {"left": set(), "right": set()}
        self._items = tuple(renderer._board_items(self._R, C, [b for b in boards if b[0] not in hidden[cam]])
                            for cam, C in zip(("left", "right"), self._centres))
        self._rng = np.random.default_rng(noise_seed)
        self.stats = {"draws": 0, "pixels": 0, "draw_s": 0.0} if stats is None else stats

    def draw(self, right: bool, level: int, x0: int, y0: int, width: int, height: int) -> np.ndarray:
        """The ``height`` × ``width`` (uint8) box of pyramid level ``level`` of the left (``right``
        false) or right image whose top-left full-resolution pixel is (x0, y0): level pixel (i, j)
        stands for the full-resolution pixels [x0 + i·2^L, x0 + (i+1)·2^L) × [y0 + j·2^L, …)."""
        r = self.renderer.rig
        vals = (level, x0, y0, width, height)
        if any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in vals) or not 0 <= level <= 16:
            raise ValueError(f"draw(level={level!r}, x0={x0!r}, y0={y0!r}, width={width!r}, height={height!r}): "
                             f"must be integers, level in [0, 16]")
        k = 1 << int(level)
        if not (width > 0 and height > 0 and x0 >= 0 and y0 >= 0 and x0 + width * k <= r.width
                and y0 + height * k <= r.height):
            raise ValueError(f"draw box ({x0}, {y0}) + {width}x{height} at level {level} is not inside the "
                             f"{r.width}x{r.height} image")
        t0 = time.perf_counter()
        cam = 1 if right else 0
        img = self.renderer.draw_level(self.pose[2], self._R, self._centres[cam], self._items[cam], int(x0),
                                       int(y0), int(width), int(height), int(level), self._rng)
        s = self.stats
        s["draws"] += 1
        s["pixels"] += int(width) * int(height)
        s["draw_s"] += time.perf_counter() - t0
        return img
