"""Textures and per-camera maps of the renderer (:mod:`safenav.vision.render`): the periodic
ground and background textures, the markers' mip pyramids, and the maps of a pinhole view
(which rows see the ground, their haze, and where each background pixel looks in the panorama),
for the rig's whole image (cached per rig) or for any view, e.g. a box of the image at a
pyramid level (:class:`~safenav.vision.pixels.FramePixels`)."""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from .detect import aruco_dictionary, marker_image
from .rig import StereoRig

__all__ = ["periodic_noise", "textures", "marker_pyramid", "view_maps", "rig_maps"]


def periodic_noise(shape: tuple[int, int], seed: int, beta: float = 1.6, lo: int = 20, hi: int = 235) -> np.ndarray:
    """A seamlessly tiling uint8 texture: white noise shaped to a 1/f^β spectrum (FFT, so periodic)."""
    rng = np.random.default_rng(seed)
    h, w = shape
    spec = np.fft.rfft2(rng.standard_normal((h, w)))
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.rfftfreq(w)[None, :]
    f = np.hypot(fx, fy)
    f[0, 0] = 1.0
    img = np.fft.irfft2(spec / f ** (beta / 2.0), s=(h, w))
    img -= np.percentile(img, 1)
    img /= max(np.percentile(img, 99), 1e-12)
    return np.clip(lo + (hi - lo) * img, 0, 255).astype(np.uint8)


@functools.lru_cache(maxsize=4)
def textures(texture_seed: int, ground_tile: int, pano_h: int, pano_w: int):
    """The ground tile, the panorama and the panorama's pyramid levels (each tiled 2×2) for a seed."""
    ground = periodic_noise((ground_tile, ground_tile), texture_seed, beta=1.4)
    pano = periodic_noise((pano_h, pano_w), texture_seed + 1, beta=1.8, lo=90, hi=250)
    return ground, pano, [np.tile(pano, (2, 2))]


@functools.lru_cache(maxsize=4096)
def marker_pyramid(dictionary: str, marker_id: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """A marker board's mip pyramid, smallest first: (grey + alpha) levels and grey levels."""
    base = marker_image(aruco_dictionary(dictionary), marker_id, cell_px=64, border_cells=1)
    pyr = [base]
    while pyr[-1].shape[0] > 8:
        pyr.append(cv2.resize(pyr[-1], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA))
    pyr = pyr[::-1]
    return [cv2.merge([m, np.full_like(m, 255)]) for m in pyr], pyr


def view_maps(f: float, cx: float, cy: float, width: int, height: int, camera_height_m: float, pitch_rad: float,
              haze_m: float, pano_w: int, pano_h: int, pano_el: tuple[float, float]):
    """(first ground row, haze per ground row, background x, y maps, background rows) of a pinhole
    view (focal ``f``, principal point ``(cx, cy)``, ``width`` × ``height`` px) at the camera height
    and pitch: a row sees the ground when its ray meets it nearer than 2 km; the background rows
    (above the ground, and two more) index the panorama by azimuth (relative to the heading) and
    elevation."""
    v = np.arange(height, dtype=np.float64)
    up = -math.cos(pitch_rad) * (v - cy) / f + math.sin(pitch_rad)   # world-up component of the ray (camera z = 1)
    ground = up < -camera_height_m / 2000.0
    v_ground = int(np.argmax(ground)) if ground.any() else height
    t = camera_height_m / np.maximum(-up[v_ground:], 1e-12)   # camera depth of the ground row
    haze = np.exp(-t / haze_m).astype(np.float32)[:, None]
    nb = min(v_ground + 2, height)
    # the ray of pixel (u, v) in the world at heading 0: R0ᵀ ((u − cx)/f, (v − cy)/f, 1), R0 =
    # camera_rotation(0, pitch) (rows right = (0, −1, 0), down = (sin p, 0, −cos p), forward =
    # (cos p, 0, sin p)), so x and z depend on the row only and y on the column only
    xn = (np.arange(width, dtype=np.float64) - cx) / f
    yn = (np.arange(nb, dtype=np.float64)[:, None] - cy) / f
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    rx, ry, rz = yn * sp + cp, -xn[None, :], sp - yn * cp
    az = np.arctan2(ry, rx)
    el = np.arctan2(rz, np.hypot(rx, ry))
    e0, e1 = pano_el
    bg_x = (-az / (2 * math.pi) * pano_w).astype(np.float32)
    bg_y = np.clip((e1 - el) / (e1 - e0) * (pano_h - 1), 0, pano_h - 1).astype(np.float32)
    return v_ground, haze, bg_x, bg_y, nb


@functools.lru_cache(maxsize=4)
def rig_maps(r: StereoRig, haze_m: float, pano_w: int, pano_h: int, pano_el: tuple[float, float]):
    """:func:`view_maps` of rig ``r``'s whole image, read-only and shared by every renderer of it."""
    out = view_maps(r.focal_length_px, r.cx, r.cy, r.width, r.height, r.camera_height_m, r.pitch_rad, haze_m,
                    pano_w, pano_h, pano_el)
    for a in out[1:4]:
        a.flags.writeable = False
    return out
