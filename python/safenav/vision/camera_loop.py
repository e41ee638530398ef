"""The camera loop through the core's LanBLoc front end (ours; [SafeNav §IV-A]).

A camera on a vehicle knows where to look only from its map and its own
estimate.  :class:`CameraFrames` is the simulator's side of that loop: each
fix step the vehicle's localizer plans where its front end will search
(``Localizer.frame_plan``: the mapped landmarks projected from the filter's
prediction, each window grown by its projected 3σ; the whole frame before
the start or when the prediction is too uncertain), :class:`CameraFrames`
hands over the pair at the true pose as pixels drawn on demand by the core
(:meth:`StereoRenderer.pixels <safenav.vision.render.StereoRenderer.pixels>`),
and ``Localizer.observe_frame`` draws exactly what its front end reads (each
region at its detection level, patches around the corners at full
resolution: ground and background textures, markers, poles, pixel noise,
what the whole image holds there, so false detections can happen there as
in a whole frame), detects, ranges, trilaterates and updates the filter
through its gate.  ``Navigator.run_frames`` drives it (``run_camera`` with
the simulated camera in the core): the same loop as for every other input.

:func:`front_end` builds the core's ``LanBLocFrontEnd`` for a world and a
:class:`~safenav.vision.rig.StereoRig`.

With ``compare_whole_frame`` each frame is also rendered whole and searched
without a prediction, to count what the estimate's windows cost
(:attr:`CameraFrames.comparison`): fixes in each mode, the markers the whole
frame found that the windows missed, and false detections (an id that is
not drawn in the image, or not a landmark) in each mode.  On that whole
rendering the plan's windows are also searched at full resolution
(``detect_side_px = 0``) beside the pyramid levels, and the Python region
pipeline (:class:`~safenav.vision.regions.RegionPipeline`, its regions from
the markers' true footprints) runs on the same pixels, for the time per frame
of each and the pyramid's agreement with full resolution.  And the plan's
windows drawn at full resolution are compared with the same windows drawn
on demand as the loop draws them: fixes, markers missed or extra, the fixes'
difference.
"""

from __future__ import annotations

import time

import numpy as np

from .. import _core
from ..world import World
from .render import StereoRenderer
from .rig import StereoRig

__all__ = ["CameraFrames", "front_end", "NOISE_STREAM"]

#: The pixel-noise stream of a frame: ``derive_seed(derive_seed(seed, NOISE_STREAM), step)``
#: (as :class:`~safenav.vision.lanbloc.CameraLoopSource`'s).
NOISE_STREAM = 2


def front_end(world: World, rig: StereoRig, *, marker_size_m: float = 1.5, dictionary: str = "DICT_4X4_100",
              min_landmarks: int = 3, **settings) -> _core.LanBLocFrontEnd:
    """The core's LanBLoc front end for ``world``'s landmarks (marker id = landmark id, the
    marker centre at the landmark's height) seen by ``rig`` (depths beyond ``rig.max_range_m``
    give no range); ``settings`` are ``_core.LanBLocSettings`` fields."""
    if not isinstance(world, World):
        raise ValueError(f"world = {world!r}: must be a safenav World")
    if not isinstance(rig, StereoRig):
        raise ValueError(f"rig = {rig!r}: must be a StereoRig")
    cam = _core.RectifiedCamera()
    cam.f, cam.cx, cam.cy, cam.baseline, cam.doffs = rig.focal_length_px, rig.cx, rig.cy, rig.baseline_m, 0.0
    cam.width, cam.height = rig.width, rig.height
    s = _core.LanBLocSettings()
    s.dictionary, s.marker_size_m, s.min_landmarks, s.max_range_m = dictionary, marker_size_m, min_landmarks, \
        rig.max_range_m
    for k, v in settings.items():
        if not hasattr(s, k):
            raise ValueError(f"{k} = {v!r}: not a LanBLocSettings field")
        setattr(s, k, v)
    return _core.LanBLocFrontEnd(_core.LanBLocRig(cam, rig.camera_height_m, rig.pitch_rad),
                                 {lm.id: (*lm.position[:2], lm.height) for lm in world.landmarks}, s)


class CameraFrames:
    """Frames for ``Navigator.run_frames``: ``frames(truth, step, plan)`` returns the pair at the
    true pose as pixels drawn on demand (:meth:`StereoRenderer.pixels
    <safenav.vision.render.StereoRenderer.pixels>`: the front end draws the plan's regions, or the
    whole frame, at its detection levels, and patches around the corners it finds), or ``None``
    when the frame cannot give a range (``early_out``: no landmark centre in the left image, a
    bound from the geometry that holds whatever the detector does with the pixels; such a frame
    counts as a dropout).

    :attr:`front_end` is the core's front end (:func:`front_end`); :meth:`run` runs one trial;
    :attr:`stats` counts frames by search mode, early outs, and the boxes drawn and their pixels.
    """

    name = "lanbloc-camera"
    emulated = False

    def __init__(self, world: World, rig: StereoRig | None = None, *, marker_size_m: float = 1.5,
                 dictionary: str = "DICT_4X4_100", noise_std: float = 1.0, occlusion: bool = True,
                 early_out: bool = True, seed: int = 0, texture_seed: int = 0, min_landmarks: int = 3,
                 compare_whole_frame: bool = False, **settings):
        from .lanbloc import CameraLoopSource
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2 ** 64:
            raise ValueError(f"seed = {seed!r}: must be an integer in [0, 2**64)")
        self.rig = CameraLoopSource.DEFAULT_RIG if rig is None else rig
        self._world, self._dictionary, self._settings = world, dictionary, dict(settings)
        self._marker_size_m = marker_size_m
        self.renderer = StereoRenderer(world, self.rig, marker_size_m=marker_size_m, dictionary=dictionary,
                                       noise_std=noise_std, seed=seed, texture_seed=texture_seed,
                                       occlusion=occlusion)
        self.front_end = front_end(world, self.rig, marker_size_m=marker_size_m, dictionary=dictionary,
                                   min_landmarks=min_landmarks, **settings)
        self.min_landmarks = int(min_landmarks)
        self.early_out = bool(early_out)
        self._noise_seed = int(_core.derive_seed(int(seed), NOISE_STREAM))
        self.compare_whole_frame = bool(compare_whole_frame)
        #: frames by search mode and early outs; the boxes the front end had drawn and their pixels
        self.stats = {"frames": 0, "windows": 0, "whole_frame": 0, "early_out": 0, "draws": 0, "pixels": 0}
        self._last = None   # the last frame's pixels, counted into stats on the next frame or after the trial
        self.comparison = {k: 0 for k in ("frames", "fixes_windows", "fixes_whole", "markers_windows",
                                          "markers_whole", "missed", "false_windows", "false_whole",
                                          "fixes_pyramid", "fixes_full_res", "markers_pyramid",
                                          "markers_full_res", "missed_pyramid", "extra_pyramid",
                                          "fixes_drawn", "markers_drawn", "missed_drawn", "extra_drawn")}
        #: per compared frame: the windows' fix error [m], NEES and farthest range [m] against the truth
        #: (fixes only), the front end's seconds in the windows and on the whole frame, and the
        #: comparison's own seconds; on the whole rendering: the front end's seconds in the plan's
        #: windows at the pyramid levels and at full resolution, the Python region pipeline's seconds,
        #: |pyramid fix − full-resolution fix| [m] (both fixes), the largest corner difference [px] of
        #: each marker both found (both images), and each one's fix error against the truth [m]; the
        #: seconds to render the plan's regions at full resolution, and to draw and search them on
        #: demand as the loop does, that fix's error and its distance from the full-resolution one [m]
        self.samples = {k: [] for k in ("error", "nees", "range", "s_windows", "s_whole", "s_compare",
                                        "s_pyramid", "s_full_res", "s_python", "fix_diff", "corner_diff",
                                        "error_pyramid", "error_full_res", "s_render_regions", "s_drawn",
                                        "error_drawn", "drawn_diff")}
        self._full_res = self._python = None

    @classmethod
    def from_scenario(cls, scenario, width: int | None = None, height: int | None = None, *,
                      camera_height_m: float = 1.5, **kwargs) -> "CameraFrames":
        """From a :class:`~safenav.scenario.Scenario`: its world, its camera (at its own resolution, or
        scaled to ``width`` px), detection range, minimum landmark count, occlusion setting and
        ranging (``camera.ranging``: the core's ``LanBLocRanging``)."""
        from .lanbloc import scenario_camera

        rig, kwargs = scenario_camera(scenario, width, height, camera_height_m, kwargs)
        kwargs.setdefault("ranging", getattr(_core.LanBLocRanging, scenario.camera.ranging.upper()))
        return cls(scenario.world, rig, **kwargs)

    def run(self, navigator, seed: int):
        """One trial of ``navigator`` (a ``Navigator``) with these frames in the loop: in the core
        (``Navigator.run_camera``, the frames drawn by the renderer's simulated camera with the same
        noise streams as :meth:`__call__`), or through :meth:`__call__` with ``compare_whole_frame``."""
        if not self.compare_whole_frame:
            # the whole camera loop in the core: frames drawn by its simulated camera, no Python per frame
            r, counts = navigator.run_camera(int(seed), self.front_end, self.renderer.camera(),
                                             self.renderer.pixel_noise(), self._noise_seed, self.early_out)
            for k, v in counts.items():
                self.stats[k] += v
            return r
        try:
            return navigator.run_frames(int(seed), self.front_end, self)
        finally:
            self._count_drawn()

    def __call__(self, truth, step: int, plan):
        s = np.asarray(truth, dtype=float).ravel()
        if s.shape != (4,) or not np.isfinite(s).all():
            raise ValueError(f"truth = {truth!r}: must be a finite (x, y, v, theta)")
        pose = (s[0], s[1], s[3])
        self.stats["frames"] += 1
        # a frame with fewer landmarks than a fix needs still gives their ranges and bearings
        # (Navigator.run_frames updates with FrameUpdate.FIX_OR_LANDMARKS): only an empty view is skipped
        if self.early_out and self.renderer.centres_in_view(pose) < 1:
            self.stats["early_out"] += 1
            return None
        seed = int(_core.derive_seed(self._noise_seed, int(step)))
        whole = plan.mode == _core.SearchMode.WHOLE_FRAME
        self.stats["whole_frame" if whole else "windows"] += 1
        if self.compare_whole_frame and not whole:
            t1 = time.perf_counter()
            self._compare(pose, seed, plan)
            self.samples["s_compare"].append(time.perf_counter() - t1)
        # the front end draws what it reads: each region at its pyramid level, patches around the corners
        self._count_drawn()
        self._last = self.renderer.pixels(pose, seed)
        return self._last

    def _count_drawn(self) -> None:
        if self._last is not None:
            self.stats["draws"] += self._last.draws
            self.stats["pixels"] += self._last.pixels
            self._last = None

    def _compare(self, pose, seed: int, plan) -> None:
        """The same frame searched in the plan's windows (drawn at full resolution, and as the loop
        draws them: on demand at the detection levels) and in the whole (rendered) frame."""
        full = [(0, 0, self.rig.width, self.rig.height)]
        t = time.perf_counter()
        left, right = self.renderer.render_regions(pose, plan.left_regions, plan.right_regions, seed)
        self.samples["s_render_regions"].append(time.perf_counter() - t)
        wl, wr = self.renderer.render_regions(pose, full, full, seed)
        t0 = time.perf_counter()
        fw = self.front_end.localize_plan(left, right, plan)
        t1 = time.perf_counter()
        ff = self.front_end.localize(wl, wr)
        self.samples["s_windows"].append(t1 - t0)
        t2 = time.perf_counter()
        self.samples["s_whole"].append(t2 - t1)
        fd = self.front_end.localize_pixels(self.renderer.pixels(pose, seed), plan)
        self.samples["s_drawn"].append(time.perf_counter() - t2)
        self._compare_drawn(fw, fd, pose)
        if fw.ok:
            e = np.asarray(fw.position) - pose[:2]
            self.samples["error"].append(float(np.hypot(*e)))
            self.samples["nees"].append(float(e @ np.linalg.solve(fw.covariance, e)))
            self.samples["range"].append(max(o.range for o in fw.observations if o.ok))
        self._compare_levels(pose, seed, plan, wl, wr)
        drawn = set(self.renderer.frame(pose, seed).footprints("left"))   # geometry only: no pixels drawn
        c = self.comparison
        c["frames"] += 1
        c["fixes_windows"] += fw.ok
        c["fixes_whole"] += ff.ok
        ids_w = {o.landmark_id for o in fw.observations}
        ids_f = {o.landmark_id for o in ff.observations}
        c["markers_windows"] += len(ids_w)
        c["markers_whole"] += len(ids_f)
        c["missed"] += len(ids_f - ids_w)
        c["false_windows"] += len(ids_w - drawn) + len(fw.unmapped)
        c["false_whole"] += len(ids_f - drawn) + len(ff.unmapped)

    def _compare_drawn(self, fw, fd, pose) -> None:
        """The windows drawn on demand at the detection levels (the loop's pixels) against the same
        windows drawn at full resolution: fixes, markers each found that the other did not, and the
        fixes' difference and error."""
        c, s = self.comparison, self.samples
        c["fixes_drawn"] += fd.ok
        iw, idr = ({o.landmark_id for o in f.observations} for f in (fw, fd))
        c["markers_drawn"] += len(idr)
        c["missed_drawn"] += len(iw - idr)
        c["extra_drawn"] += len(idr - iw)
        if fd.ok:
            s["error_drawn"].append(float(np.hypot(*(np.asarray(fd.position) - pose[:2]))))
        if fd.ok and fw.ok:
            s["drawn_diff"].append(float(np.hypot(*(np.asarray(fd.position) - np.asarray(fw.position)))))

    def _compare_levels(self, pose, seed: int, plan, wl, wr) -> None:
        """On the whole rendering: the plan's windows at the pyramid levels and at full resolution,
        and the Python region pipeline, timed; the pyramid's agreement with full resolution."""
        from .detect import FiducialDetector
        from .lanbloc import LanBLoc

        if self._full_res is None:
            kw = dict(self._settings, detect_side_px=0.0)
            self._full_res = front_end(self._world, self.rig, marker_size_m=self._marker_size_m,
                                       dictionary=self._dictionary, min_landmarks=self.min_landmarks, **kw)
            self._python = LanBLoc(self._world, self.rig, FiducialDetector(self._world, dictionary=self._dictionary,
                                                                           aruco3=True),
                                   ranging="corners", min_landmarks=self.min_landmarks,
                                   max_range_m=self.rig.max_range_m)
        t0 = time.perf_counter()
        fp = self.front_end.localize_plan(wl, wr, plan)
        t1 = time.perf_counter()
        fr = self._full_res.localize_plan(wl, wr, plan)
        t2 = time.perf_counter()
        frame = self.renderer.frame(pose, seed, images=(wl, wr))
        t3 = time.perf_counter()
        self._python.localize_frame(frame)
        t4 = time.perf_counter()
        s, c = self.samples, self.comparison
        s["s_pyramid"].append(t1 - t0)
        s["s_full_res"].append(t2 - t1)
        s["s_python"].append(t4 - t3)
        c["fixes_pyramid"] += fp.ok
        c["fixes_full_res"] += fr.ok
        for res, key in ((fp, "error_pyramid"), (fr, "error_full_res")):
            if res.ok:
                s[key].append(float(np.hypot(*(np.asarray(res.position) - pose[:2]))))
        if fp.ok and fr.ok:
            s["fix_diff"].append(float(np.hypot(*(np.asarray(fp.position) - np.asarray(fr.position)))))
        ip = {o.landmark_id: o for o in fp.observations}
        ir = {o.landmark_id: o for o in fr.observations}
        c["markers_pyramid"] += len(ip)
        c["markers_full_res"] += len(ir)
        c["missed_pyramid"] += len(set(ir) - set(ip))
        c["extra_pyramid"] += len(set(ip) - set(ir))
        for i in set(ip) & set(ir):
            d = np.abs(np.vstack([ip[i].corners_left, ip[i].corners_right])
                       - np.vstack([ir[i].corners_left, ir[i].corners_right]))
            if np.isfinite(d).any():
                s["corner_diff"].append(float(np.nanmax(d)))
