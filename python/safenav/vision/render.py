"""Camera-in-the-loop rendering: the stereo pair a vehicle sees.

:class:`StereoRenderer` draws the left and right images of an ideal,
already rectified stereo rig (:class:`~safenav.vision.rig.StereoRig`: pinhole, same intrinsics
``K`` for both cameras, baseline ``B`` along the camera x axis, camera height
``h``, a fixed pitch) at a vehicle pose ``(x, y, θ)``:

* a textured ground plane (a periodic 1/f-noise tile, drawn with a
  perspective warp through the ground-to-image homography
  ``H = K [r₁ r₂ t]``, faded into haze with distance);
* a textured background at infinity (a periodic panorama indexed by azimuth
  and elevation; at infinity it has zero disparity);
* every landmark of the world as a planar fiducial marker (an ArUco or
  AprilTag image with a white quiet zone, side ``marker_size_m``) whose centre
  stands at the landmark's map position and height on a thin pole, facing the
  rig or with a fixed yaw; each marker is warped into its bounding box only,
  with an anti-aliased alpha mask, far markers first (painter's order), from
  a per-marker mip pyramid (the level just below the on-screen size, so
  the marker is only ever magnified and its edges stay where they belong).

Conventions.  World: x east, y north, z up; the heading θ is counter-clockwise
from +x.  Camera: x right, y down, z forward.  **The vehicle's position is the
left camera's centre** (OpenCV's stereo reference frame), at height ``h``; the
right camera sits ``B`` to its right.  Pixel centres are at integer
coordinates, so a camera point ``(X, Y, Z)`` projects to
``u = f·X/Z + c_x``, ``v = f·Y/Z + c_y``, and a point at depth ``Z`` has
disparity ``u_L − u_R = f·B/Z`` (the pair is rectified by construction,
``doffs = 0``).  :meth:`StereoRig.calibration` gives the matching
:class:`safenav.vision.calibration.StereoCalibration` (zero distortion, ``R = I``,
``T = (−B, 0, 0)``; ``cv2.stereoRectify`` of it is the identity) and :meth:`StereoRig.rectified_camera`
the equivalent :class:`safenav.vision.stereo.RectifiedCamera`, so LanBLoc can skip rectification.

Only landmarks inside the horizontal field of view and within
``rig.max_range_m`` are drawn (vectorised culling).  Obstacles are not drawn,
but with ``occlusion=True`` (the default when the renderer is given a
:class:`~safenav.world.World`) a landmark that an obstacle hides from a
camera's centre is not drawn in that camera's image: the core's line-of-sight
query (:meth:`safenav.world.World.visible_from`), the same one the
measurement-level visibility test and landmark placement use.  Occlusion is
per landmark (its marker's centre), not per pixel: a marker half behind a
boulder is either drawn whole or not at all.

**Pixels on demand** (:meth:`StereoRenderer.pixels`, ours; the core's ``safenav/render.hpp``).
The pixels are drawn by the core: ``_core.PixelRenderer`` holds a scene's textures and board
pyramids, ``_core.SimulatedCamera`` the geometry above (culling, facing, occlusion), and a
``_core.RenderedFrame`` draws any box of either image at any pyramid level ``L`` as the front end
asks for it (``StereoPixels``): the view whose pixel centres are the 2^L-blocks' centres (focal
f/2^L), textures read from their own level, boards blurred by the optics' point spread, pixel
noise σ/2^L from a tile of Gaussian draws at offsets that a hash of the frame's noise seed and the
pixel's block gives (a pixel's noise does not depend on what was drawn before it).  :meth:`render` and :meth:`render_regions` draw whole
images and regions through it; the camera loop draws only what its front end reads
(``docs/lanbloc_cpp.md``, "Pixels drawn on demand").

**Rendering by region** (:meth:`StereoRenderer.frame`, ours; :mod:`safenav.vision.frame`).  A
frame of the scenario's camera (2560×1440) holds a few markers covering a
small part of the image, so the camera loop renders only what it looks at.
:class:`StereoFrame` is the pair at one pose, drawn on demand: its
:meth:`~StereoFrame.regions` are the markers' footprints (the boards' pixel
boxes, known from the geometry, grown by a margin and merged where they
overlap), and :meth:`~StereoFrame.patch` draws any box of either image at any
pyramid level ``L`` (``2^L`` pixels per side averaged, the level-``L`` pixel
``i`` centred on level-0 ``(i + 0.5)·2^L − 0.5``), markers and poles in
painter's order over a cheap background (the panorama tile indexed by pixel,
which like a background at infinity has zero disparity), with pixel noise of
σ/2^L.  Outside the footprints the image is background, which holds no
marker: detecting in the regions finds what a detector would find in the
whole image, except false detections in the ground texture, which the
regions do not draw.  The cost of a frame grows with the markers in view, not
with the pixel count.
"""

from __future__ import annotations

import functools
import math
from typing import Mapping

import cv2
import numpy as np

from .. import _core
from ..world import Landmark, World
from .detect import aruco_dictionary
from .frame import StereoFrame
from .rig import StereoRig, as_pose, camera_rotation, check_positive
from .textures import marker_pyramid, periodic_noise, textures

__all__ = ["StereoRig", "StereoRenderer", "StereoFrame", "camera_rotation", "periodic_noise"]


@functools.lru_cache(maxsize=8)
def _pixel_renderer(rig: StereoRig, texture_seed: int, dictionary: str, markers: tuple, haze_m: float,
                    pole_grey: float, ground_res_m: float, ground_tile: int, pano_w: int, pano_h: int,
                    pano_el: tuple[float, float]) -> "_core.PixelRenderer":
    """The core's renderer of a scene (``_core.PixelRenderer``: the rig, the textures of
    ``texture_seed``, each landmark's board pyramid for ``markers`` = ((landmark id, marker id), …)),
    shared by every renderer of it: it computes the panorama coordinates of the rig's pixels once,
    and a camera trial makes a renderer per trial."""
    ground, pano, _ = textures(texture_seed, ground_tile, pano_h, pano_w)
    boards = {lid: marker_pyramid(dictionary, mid)[0] for lid, mid in markers}
    return _core.PixelRenderer(rig.focal_length_px, rig.cx, rig.cy, rig.width, rig.height, rig.camera_height_m,
                               rig.pitch_rad, ground, ground_res_m, pano, pano_el[0], pano_el[1], haze_m, pole_grey,
                               boards)


# --------------------------------------------------------------------------- the renderer

class StereoRenderer:
    """Renders the rectified stereo pair of ``rig`` at a vehicle pose (see the module docstring).

    Parameters
    ----------
    landmarks:
        A :class:`~safenav.world.World` or a sequence of :class:`~safenav.world.Landmark`.
    rig:
        The :class:`StereoRig`.
    marker_size_m:
        Side of the black-framed marker [m]; the white quiet zone adds one
        cell on each side.
    dictionary:
        ``cv2.aruco`` dictionary of the markers (must hold every marker id).
    marker_ids:
        ``landmark id → marker id`` (default: the landmark id itself).
    facing:
        ``"camera"`` (each marker turns toward the rig, about the vertical) or
        a yaw [rad] for every marker, or a mapping ``landmark id → yaw``; the
        yaw is the direction the marker's face points to.  A marker seen
        from behind is not drawn.
    color:
        ``False`` renders (H, W) grey images, ``True`` (H, W, 3) BGR.
    noise_std:
        Standard deviation of additive Gaussian pixel noise (independent in
        the two images), drawn from a generator seeded with ``seed``.
    texture_seed:
        Seed of the ground and background textures.
    occlusion:
        Obstacles hide the landmarks behind them (see the module docstring);
        default: on when ``landmarks`` is a World.
    """

    GROUND_RES_M = 0.02      # ground texture: metres per texel
    GROUND_TILE = 1024       # texels per tile side (period 20.48 m)
    PANO_W, PANO_H, PANO_EL = 4096, 1024, (-0.35, 0.9)   # panorama size and elevations covered [rad]
    HAZE_M, POLE_WIDTH_M = 80.0, 0.08   # ground contrast falls as exp(-Z / HAZE_M); pole width [m]
    POLE_GREY = 70.0         # grey level of the poles
    NOISE_TILE = 512         # side of the pixel-noise tile of StereoFrame patches
    REGION_NOISE_TILE = 256   # side of the pixel-noise tile of pixels() (small: it is read from cache)

    def __init__(self, landmarks, rig: StereoRig | None = None, *, marker_size_m: float = 1.5,
                 dictionary: str = "DICT_4X4_100", marker_ids: Mapping[int, int] | None = None,
                 facing: str | float | Mapping[int, float] = "camera", color: bool = False,
                 noise_std: float = 0.0, seed: int = 0, texture_seed: int = 0, occlusion: bool | None = None):
        self.rig = StereoRig() if rig is None else rig
        if not isinstance(self.rig, StereoRig):
            raise ValueError(f"rig = {rig!r}: must be a StereoRig")
        self.world = landmarks if isinstance(landmarks, World) else None
        if occlusion is None:
            occlusion = self.world is not None
        if occlusion and self.world is None:
            raise ValueError("occlusion = True needs the World (its obstacles), not a landmark list")
        #: obstacles hide landmarks (per landmark, by the core's line-of-sight query)
        self.occlusion = bool(occlusion) and bool(self.world.obstacles)
        lms = landmarks.landmarks if isinstance(landmarks, World) else tuple(landmarks)
        for i, lm in enumerate(lms):
            if not isinstance(lm, Landmark):
                raise ValueError(f"landmarks[{i}] = {lm!r}: must be a Landmark")
        self.landmarks: tuple[Landmark, ...] = tuple(lms)
        self.marker_size_m = check_positive("marker_size_m", marker_size_m)
        self.dictionary = aruco_dictionary(dictionary)
        self.dictionary_name = dictionary
        n_dict = int(self.dictionary.bytesList.shape[0])
        marker_ids = {} if marker_ids is None else dict(marker_ids)
        self._marker_id = {}
        for lm in self.landmarks:
            mid = marker_ids.get(lm.id, lm.id)
            if isinstance(mid, bool) or not isinstance(mid, (int, np.integer)) or not 0 <= mid < n_dict:
                raise ValueError(f"landmark {lm.id}: marker id {mid!r} is not in dictionary {dictionary} "
                                 f"(ids 0..{n_dict - 1}); pass marker_ids or a larger dictionary")
            self._marker_id[lm.id] = int(mid)
        if isinstance(facing, str):
            if facing != "camera":
                raise ValueError(f"facing = {facing!r}: must be 'camera', a yaw in radians or a mapping id -> yaw")
            self._yaw = None
        elif isinstance(facing, Mapping):
            self._yaw = np.array([float(facing.get(lm.id, np.nan)) for lm in self.landmarks])
            missing = [lm.id for lm, y in zip(self.landmarks, self._yaw) if not math.isfinite(y)]
            if missing:
                raise ValueError(f"facing: no finite yaw for landmark {missing[0]}")
        else:
            y = float(facing)
            if not math.isfinite(y):
                raise ValueError(f"facing = {facing!r}: must be finite")
            self._yaw = np.full(len(self.landmarks), y)
        self.color = bool(color)
        self.noise_std = check_positive("noise_std", noise_std, allow_zero=True)
        self._rng = np.random.default_rng(seed)
        self._L = np.array([(*lm.position[:2], lm.height) for lm in self.landmarks], float).reshape(-1, 3)
        # textures (shared by every renderer with this texture seed)
        # the panorama's levels for StereoFrame's cheap background (the core draws everything else)
        self._pano_levels = textures(int(texture_seed), self.GROUND_TILE, self.PANO_H, self.PANO_W)[2]
        self._seed = seed
        self._texture_seed = int(texture_seed)
        self._noise_tile = None
        self._pixel_noise = None   # the pixel-noise tile of pixels() (a _core.RenderNoise), made on first use
        self._camera = None        # the core's simulated camera (camera()), made on first use

    # ---- public API
    def calibration(self):
        """The rig's :class:`safenav.vision.calibration.StereoCalibration` (images are already rectified)."""
        return self.rig.calibration()

    def project(self, pose, points, camera: str = "left") -> tuple[np.ndarray, np.ndarray]:
        """Pinhole projection of world ``points`` (N, 3) into ``camera``: ``(uv (N, 2), depth Z (N,))``."""
        if camera not in ("left", "right"):
            raise ValueError(f"camera = {camera!r}: must be 'left' or 'right'")
        x, y, th = as_pose(pose)
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        R = camera_rotation(th, self.rig.pitch_rad)
        C = self.rig.camera_centers((x, y, th))[0 if camera == "left" else 1]
        pc = (P - C) @ R.T
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = self.rig.focal_length_px * pc[:, :2] / pc[:, 2:3] + [self.rig.cx, self.rig.cy]
        return uv, pc[:, 2]

    def culled(self, pose) -> np.ndarray:
        """Indices of the landmarks that pass the cheap cull: within range and the horizontal field of view."""
        if len(self.landmarks) == 0:
            return np.zeros(0, dtype=int)
        x, y, th = as_pose(pose)
        C = np.array([x, y, self.rig.camera_height_m])
        d = self._L - C
        dist = np.linalg.norm(d, axis=1)
        fwd = d[:, 0] * math.cos(th) + d[:, 1] * math.sin(th)
        lat = d[:, 0] * math.sin(th) - d[:, 1] * math.cos(th)
        half = 0.5 * self.rig.horizontal_fov_rad
        ang = np.abs(np.arctan2(lat, fwd))
        slack = np.arctan2(self._board_half_m + self.rig.baseline_m, np.maximum(np.hypot(fwd, lat), 1e-9))
        keep = (dist <= self.rig.max_range_m) & (fwd > self.rig.near_m) & (ang <= half + slack)
        return np.flatnonzero(keep)

    def marker_corners(self, pose) -> dict[int, np.ndarray]:
        """World corners (4, 3) of the black-framed marker of every culled landmark (TL, TR, BR, BL)."""
        out = {}
        for i in self.culled(pose):
            c, a, up = self._frame(i, pose)
            s = 0.5 * self.marker_size_m
            out[self.landmarks[i].id] = np.array([c - a * s + up * s, c + a * s + up * s,
                                                  c + a * s - up * s, c - a * s - up * s])
        return out

    def visible(self, pose, margin_px: float = 2.0, min_side_px: float = 0.0) -> list[int]:
        """Landmark ids whose whole marker lies inside both images, faces the rig, has sides of at
        least ``min_side_px`` and is not hidden, even in part, by a nearer marker's board (both images)."""
        x, y, th = as_pose(pose)
        boxes = {}   # (camera, id) -> board bounding box and depth, for the occlusion test
        for i in self.culled(pose):
            lid, board, _, facing = self._board(i, (x, y, th))
            if not facing:
                continue
            for cam in ("left", "right"):
                uv, z = self.project(pose, board, cam)
                if (z > self.rig.near_m).all():
                    boxes[cam, lid] = (uv.min(axis=0), uv.max(axis=0), float(z.mean()))
        ids = []
        hidden = self.hidden(pose)
        for lid, corners in self.marker_corners(pose).items():
            ok = self._faces(pose, lid)
            for cam in ("left", "right"):
                if not ok or lid in hidden[cam]:
                    ok = False
                    break
                uv, z = self.project(pose, corners, cam)
                if (z <= self.rig.near_m).any() or (uv < margin_px).any() \
                        or (uv[:, 0] > self.rig.width - 1 - margin_px).any() \
                        or (uv[:, 1] > self.rig.height - 1 - margin_px).any():
                    ok = False
                    break
                side = np.linalg.norm(np.diff(np.vstack([uv, uv[:1]]), axis=0), axis=1).min()
                if side < min_side_px:
                    ok = False
                    break
                lo, hi, zm = uv.min(axis=0), uv.max(axis=0), float(z.mean())
                for (c, other), (olo, ohi, oz) in boxes.items():
                    if c == cam and other != lid and oz < zm and (olo < hi).all() and (ohi > lo).all():
                        ok = False
                        break
            if ok:
                ids.append(lid)
        return ids

    def render(self, pose) -> tuple[np.ndarray, np.ndarray]:
        """The rectified ``(left, right)`` images at ``pose = (x, y, θ)`` (or a state (x, y, v, θ)): each
        whole image drawn by the core (:meth:`pixels` at level 0, without its noise), then pixel noise
        of fresh draws from the renderer's running stream, truncated."""
        px = self.pixels(pose, noise=False)
        w, h = self.rig.width, self.rig.height
        out = []
        for right in (False, True):
            img = px.draw(right, 0, 0, 0, w, h)
            if self.noise_std > 0:
                noise = self._rng.standard_normal(img.shape, dtype=np.float32) * self.noise_std
                img = np.clip(img + noise, 0, 255).astype(np.uint8)
            out.append(img if not self.color else cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
        return out[0], out[1]

    def render_regions(self, pose, left_regions, right_regions, noise_seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """The grey rectified pair at ``pose`` drawn only in the given regions of each image (boxes
        ``(x0, y0, x1, y1)``, ends exclusive; the rest stays 0): in each, what :meth:`render` draws
        there (ground and background textures, markers, poles) and pixel noise from the stream
        ``noise_seed``.  A detector that searches only these regions sees the whole image's pixels
        there, false detections in the textures included.  The regions are drawn as :meth:`pixels`
        draws boxes at level 0, left then right."""
        px = self.pixels(pose, noise_seed)
        w, h = self.rig.width, self.rig.height
        out = []
        for right, regions in ((False, left_regions), (True, right_regions)):
            img = np.zeros((h, w), np.uint8)
            for box in regions:
                x0, y0, x1, y1 = (int(round(float(v))) for v in box)
                if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
                    raise ValueError(f"region {tuple(box)}: must lie inside the {w}x{h} image with x0 < x1, y0 < y1")
                img[y0:y1, x0:x1] = px.draw(right, 0, x0, y0, x1 - x0, y1 - y0)
            out.append(img)
        return out[0], out[1]

    def pixels(self, pose, noise_seed: int = 0, noise: bool = True):
        """The pair at ``pose`` drawn box by box on demand by the core (``_core.RenderedFrame``, the
        front end's ``StereoPixels``; see "Pixels on demand" above): ``draw(right, level, x0, y0,
        width, height)`` gives the box of pyramid level ``level`` whose top-left full-resolution pixel
        is (x0, y0).  The boards' geometry (culling, occlusion, facing, projection) is the core's
        camera's (:meth:`camera`), computed once per frame.  Pixel noise (``noise``): windows of a
        tile of N(0, σ²) draws fixed by the renderer's seed, at offsets from the stream ``noise_seed``."""
        return self.camera().frame(np.array(as_pose(pose), float), self.pixel_noise() if noise else None,
                                   int(noise_seed) % 2 ** 64)

    def pixel_noise(self):
        """The pixel noise of :meth:`pixels` (``_core.RenderNoise``; ``None`` without noise)."""
        if self.noise_std > 0 and self._pixel_noise is None:
            self._pixel_noise = _core.RenderNoise(self.noise_std, int(_core.derive_seed(int(self._seed) % 2 ** 64, 11)),
                                                  self.REGION_NOISE_TILE)
        return self._pixel_noise

    def camera(self):
        """The core's simulated camera of this renderer (``_core.SimulatedCamera``: its landmarks'
        boards, facing and occlusion, drawn by the shared ``_core.PixelRenderer`` of its scene)."""
        if self._camera is None:
            r = self.rig
            renderer = _pixel_renderer(r, self._texture_seed, self.dictionary_name,
                                       tuple((lm.id, self._marker_id[lm.id]) for lm in self.landmarks), self.HAZE_M,
                                       self.POLE_GREY, self.GROUND_RES_M, self.GROUND_TILE, self.PANO_W,
                                       self.PANO_H, self.PANO_EL)
            boards = [(lm.id, self._L[i], None if self._yaw is None else float(self._yaw[i]))
                      for i, lm in enumerate(self.landmarks)]
            self._camera = _core.SimulatedCamera(renderer, boards, r.baseline_m, r.max_range_m, r.near_m,
                                                 self._board_half_m, self.POLE_WIDTH_M,
                                                 self.world._checker if self.occlusion else None)
        return self._camera

    def centres_in_view(self, pose) -> int:
        """How many landmarks have their marker's centre inside the left image and are not hidden (the
        core's camera): a bound on the whole markers a detector can find there (a marker wholly in the
        image has its centre in it), much cheaper than drawing the frame."""
        return self.camera().centres_in_view(np.array(as_pose(pose), float))

    def hidden(self, pose) -> dict[str, set[int]]:
        """``{"left": ids, "right": ids}``: the culled landmarks that an obstacle hides from each
        camera's centre (the core's line-of-sight query); empty sets without occlusion."""
        out = {"left": set(), "right": set()}
        idx = self.culled(pose)
        if not self.occlusion or len(idx) == 0:
            return out
        for cam, C in zip(("left", "right"), self.rig.camera_centers(as_pose(pose))):
            seen = self.world.visible_from(C[:2], self._L[idx, :2])
            out[cam] = {self.landmarks[i].id for i, v in zip(idx, seen) if not v}
        return out

    def frame(self, pose, noise_seed: int | None = None, images=None) -> "StereoFrame":
        """The stereo pair at ``pose``, rendered region by region on demand (:class:`StereoFrame`).
        ``noise_seed``: the frame's own pixel-noise stream (so a frame's pixels do not depend on which
        frames were drawn before it); default: the renderer's running stream.  ``images``: a pair
        ``(left, right)`` already rendered at ``pose``, whose pixels the frame's patches are cut from
        (the geometry, regions and footprints still come from the renderer)."""
        return StereoFrame(self, pose, noise_seed, images)

    # ---- internals
    @property
    def _board_half_m(self) -> float:
        cells = self.dictionary.markerSize + 2
        return 0.5 * self.marker_size_m * (cells + 2) / cells

    def _frame(self, i: int, pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Centre, in-plane right axis and up axis of landmark ``i``'s marker."""
        c = self._L[i]
        if self._yaw is None:
            x, y, th = as_pose(pose)
            mid = np.array([x, y]) + 0.5 * self.rig.baseline_m * np.array([math.sin(th), -math.cos(th)])
            n = mid - c[:2]
            nn = math.hypot(*n)
            n = n / nn if nn > 1e-9 else np.array([-math.cos(th), -math.sin(th)])
        else:
            n = np.array([math.cos(self._yaw[i]), math.sin(self._yaw[i])])
        a = np.array([-n[1], n[0], 0.0])   # the viewer's right when facing the marker
        return c, a, np.array([0.0, 0.0, 1.0])

    def _faces(self, pose, lid: int) -> bool:
        i = next(k for k, lm in enumerate(self.landmarks) if lm.id == lid)
        c, a, _ = self._frame(i, pose)
        n = np.array([a[1], -a[0]])
        x, y, _th = as_pose(pose)
        return float(n @ (np.array([x, y]) - c[:2])) > 0

    def _board(self, i: int, pose):
        c, a, up = self._frame(i, pose)
        hb = self._board_half_m
        corners = np.array([c - a * hb + up * hb, c + a * hb + up * hb, c + a * hb - up * hb, c - a * hb - up * hb])
        n = np.array([a[1], -a[0]])
        x, y, _ = as_pose(pose)
        facing = float(n @ (np.array([x, y]) - c[:2])) > 0
        bottom = c[2] - hb
        pw = 0.5 * self.POLE_WIDTH_M
        pole = None
        if bottom > 0:
            pole = np.array([c - a * pw + up * (bottom - c[2]), c + a * pw + up * (bottom - c[2]),
                             c + a * pw - up * c[2], c - a * pw - up * c[2]])
        return self.landmarks[i].id, corners, pole, facing

    def _pyramid(self, lid: int, grey: bool = False) -> list[np.ndarray]:
        return marker_pyramid(self.dictionary_name, self._marker_id[lid])[1 if grey else 0]

    def _warp_marker(self, img: np.ndarray, lid: int, uv: np.ndarray, side: float) -> None:
        """Warp landmark ``lid``'s board straight into ``img`` (uint8, in place) with its corners at
        pixels ``uv`` (4, 2) and its longest side ``side`` [px] (``BORDER_TRANSPARENT``: pixels that
        sample outside the board keep the background, so the board's outer edge, the quiet zone's,
        is not smoothed): the quick warp of :class:`StereoFrame`'s patches.  The loop's frames are
        drawn by the core with an alpha edge (:meth:`pixels`)."""
        h, w = img.shape
        uv = np.asarray(uv, dtype=np.float64)
        lo, hi = uv.min(axis=0), uv.max(axis=0)
        x0, y0 = max(math.floor(lo[0]) - 1, 0), max(math.floor(lo[1]) - 1, 0)
        x1, y1 = min(math.ceil(hi[0]) + 2, w), min(math.ceil(hi[1]) + 2, h)
        if x1 <= x0 or y1 <= y0:
            return
        pyr = self._pyramid(lid, grey=True)
        # the largest level not bigger than on screen: magnified by 1-2x, bilinear keeps each
        # step edge's ramp symmetric about the true edge (minifying would alias edges by ~0.1 px)
        tex = next((p for p in reversed(pyr) if p.shape[0] <= side), pyr[0])
        s = tex.shape[0]
        src = np.array([[-0.5, -0.5], [s - 0.5, -0.5], [s - 0.5, s - 0.5], [-0.5, s - 0.5]], np.float32)
        M = cv2.getPerspectiveTransform(src, (uv - [x0, y0]).astype(np.float32))
        cv2.warpPerspective(tex, M, (x1 - x0, y1 - y0), dst=img[y0:y1, x0:x1], flags=cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_TRANSPARENT)

    def _background_patch(self, level: int, X0: int, Y0: int, X1: int, Y1: int, shift: int) -> np.ndarray:
        """Level-``level`` pixels [X0, X1) × [Y0, Y1) of the cheap background of :class:`StereoFrame`:
        the panorama tile (at that pyramid level) indexed by pixel, shifted by ``shift`` columns."""
        levels = self._pano_levels
        while len(levels) <= level:
            half = cv2.resize(levels[-1][:self.PANO_H >> len(levels) - 1, :self.PANO_W >> len(levels) - 1], None,
                              fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
            levels.append(np.tile(half, (2, 2)))   # twice the period each way: any window up to one period is a slice
        tile = levels[level]
        th, tw = self.PANO_H >> level, self.PANO_W >> level
        if Y1 - Y0 <= th and X1 - X0 <= tw:
            r0, c0 = Y0 % th, (X0 + shift) % tw
            return tile[r0:r0 + Y1 - Y0, c0:c0 + X1 - X0].copy()
        rows = np.arange(Y0, Y1) % th
        cols = (np.arange(X0, X1) + shift) % tw
        return tile[rows[:, None], cols[None, :]]

    def _noise(self, shape: tuple[int, int], std: float, rng: np.random.Generator, offset) -> np.ndarray:
        """Pixel noise N(0, std²) of ``shape`` for a patch: a window of a fixed tile of Gaussian draws at
        ``offset`` (two integers in [0, NOISE_TILE)); fresh draws from ``rng`` for a patch larger than
        the tile."""
        n = self.NOISE_TILE
        if shape[0] > n or shape[1] > n:
            return rng.standard_normal(shape, dtype=np.float32) * np.float32(std)
        if self._noise_tile is None:
            t = np.random.default_rng([self._seed, 7]).standard_normal((n, n), dtype=np.float32)
            self._noise_tile = np.tile(t, (2, 2))
        r0, c0 = offset
        return self._noise_tile[r0:r0 + shape[0], c0:c0 + shape[1]] * np.float32(std)
