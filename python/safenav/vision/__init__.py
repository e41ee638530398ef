"""LanBLoc's vision front end [SafeNav §IV-A]: from a stereo
pair to a position fix.

* :mod:`~safenav.vision.stereo` — stereo calibration, rectification and SGBM
  ranging (C++ over OpenCV);
* :mod:`~safenav.vision.detect` — landmark recognition (ArUco/AprilTag
  markers, or a YOLO ONNX model);
* :mod:`~safenav.vision.localization` — trilateration and bearing
  triangulation from landmark anchors (C++/Eigen);
* :mod:`~safenav.vision.render` — the stereo pair a vehicle sees, rendered
  for the camera loop;
* :mod:`~safenav.vision.lanbloc` — the pipeline (:class:`LanBLoc`) and the
  camera loop as a navigation position source (:class:`CameraLoopSource`).
"""

from .detect import (Detection, Detector, FiducialDetector, YoloOnnxDetector, aruco_dictionary, as_gray,
                     check_image, decode_yolo, letterbox, marker_image)
from .lanbloc import STATUSES, CameraLoopSource, LanBLoc, LanBLocResult, LandmarkObservation
from .localization import LocalizationResult, LocalizationStatus, horizontal_range, triangulate_bearings, trilaterate
from .render import StereoFrame, StereoRenderer, StereoRig, camera_rotation, periodic_noise
from .stereo import (SGBM_DEFAULTS, BoxRange, DisparityScores, RectifiedCamera, SgbmMode, StereoCalibration,
                     StereoMatcher, disparity_range, disparity_scores)

__all__ = [
    "StereoCalibration", "RectifiedCamera", "StereoMatcher", "BoxRange", "SgbmMode", "SGBM_DEFAULTS",
    "disparity_range", "DisparityScores", "disparity_scores",
    "Detection", "Detector", "FiducialDetector", "YoloOnnxDetector", "aruco_dictionary", "marker_image",
    "letterbox", "decode_yolo", "as_gray", "check_image",
    "LocalizationResult", "LocalizationStatus", "trilaterate", "triangulate_bearings", "horizontal_range",
    "StereoRig", "StereoRenderer", "StereoFrame", "camera_rotation", "periodic_noise",
    "LandmarkObservation", "LanBLocResult", "LanBLoc", "CameraLoopSource", "STATUSES",
]
