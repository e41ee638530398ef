"""LanBLoc's vision front end [SafeNav §IV-A]: from a stereo
pair to a position fix.

* :mod:`~safenav.vision.stereo` — rectification and SGBM ranging (C++ over
  OpenCV), with the calibration in :mod:`~safenav.vision.calibration` and
  Middlebury-style scoring in :mod:`~safenav.vision.scores`;
* :mod:`~safenav.vision.detect` — landmark recognition (ArUco/AprilTag
  markers, or a YOLO ONNX model);
* :mod:`~safenav.vision.localization` — trilateration and bearing
  triangulation from landmark anchors (C++/Eigen);
* :mod:`~safenav.vision.render` — the stereo pair a vehicle sees, rendered
  for the camera loop (the rig in :mod:`~safenav.vision.rig`, rendering by
  region in :mod:`~safenav.vision.frame`);
* :mod:`~safenav.vision.lanbloc` — the pipeline (:class:`LanBLoc`) and the
  camera loop as a navigation position source (:class:`CameraLoopSource`);
  its parts: :mod:`~safenav.vision.full_frame` (whole stereo pairs),
  :mod:`~safenav.vision.regions` (rendered frames, region by region) and
  :mod:`~safenav.vision.ranging` (ranges, bearings and trilateration, shared),
  with the results in :mod:`~safenav.vision.sighting`.
"""

from .calibration import StereoCalibration
from .detect import (Detection, Detector, FiducialDetector, YoloOnnxDetector, aruco_dictionary, as_gray,
                     check_image, decode_yolo, letterbox, marker_image)
from .frame import StereoFrame
from .full_frame import FullFramePipeline
from .lanbloc import CameraLoopSource, LanBLoc
from .localization import LocalizationResult, LocalizationStatus, horizontal_range, triangulate_bearings, trilaterate
from .ranging import LandmarkRanging
from .regions import RegionPipeline
from .render import StereoRenderer, periodic_noise
from .rig import StereoRig, camera_rotation
from .scores import DisparityScores, disparity_scores
from .sighting import STATUSES, LandmarkSighting, LanBLocResult
from .stereo import SGBM_DEFAULTS, BoxRange, RectifiedCamera, SgbmMode, StereoMatcher, disparity_range

__all__ = [
    "StereoCalibration", "RectifiedCamera", "StereoMatcher", "BoxRange", "SgbmMode", "SGBM_DEFAULTS",
    "disparity_range", "DisparityScores", "disparity_scores",
    "Detection", "Detector", "FiducialDetector", "YoloOnnxDetector", "aruco_dictionary", "marker_image",
    "letterbox", "decode_yolo", "as_gray", "check_image",
    "LocalizationResult", "LocalizationStatus", "trilaterate", "triangulate_bearings", "horizontal_range",
    "StereoRig", "StereoRenderer", "StereoFrame", "camera_rotation", "periodic_noise",
    "LandmarkSighting", "LanBLocResult", "LanBLoc", "CameraLoopSource", "STATUSES",
    "LandmarkRanging", "FullFramePipeline", "RegionPipeline",
]
