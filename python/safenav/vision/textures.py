"""Textures of the renderer (:mod:`safenav.vision.render`): the periodic ground and background
textures and the markers' mip pyramids, made once per seed and marker and handed to the core's
renderer (``_core.PixelRenderer``), which draws with them."""

from __future__ import annotations

import functools

import cv2
import numpy as np

from .detect import aruco_dictionary, marker_image

__all__ = ["periodic_noise", "textures", "marker_pyramid"]


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
