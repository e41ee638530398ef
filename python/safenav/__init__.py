"""safenav — navigating safely without GPS.

Implements the SafeNav paper (LanBLoc localization, the Battlefield Motion
Model with EKF/PF, SafeNav corridor navigation) and the landmark placement
paper.  The heavy lifting is in the C++ core ``safenav._core``.
"""

from .datasets import SyntheticConfig, SyntheticTrajectory, synthetic_trajectory
from .filters import Ekf, FilterResult, InformationFilter, ParticleFilter, filter_trajectory
from .measurement import LANBLOC_STD, MeasurementKind, MeasurementModel, PositionNoise
from .metrics import RiskZones, TrajectoryMetrics, evaluate
from .motion import Bmm, BmmParams, wrap_angle
from .geometry import Corridor, PathSegments
from .scenario import Scenario, default_scenario, load_scenario, save_scenario
from .world import World, ScenarioError
from .vision import RectifiedCamera, StereoCalibration, StereoMatcher, triangulate_bearings, trilaterate
from . import navigation, runner

__version__ = "0.1.0"

__all__ = [
    "Bmm", "BmmParams", "wrap_angle",
    "MeasurementKind", "MeasurementModel", "PositionNoise", "LANBLOC_STD",
    "Ekf", "ParticleFilter", "InformationFilter", "filter_trajectory", "FilterResult",
    "RiskZones", "TrajectoryMetrics", "evaluate",
    "SyntheticConfig", "SyntheticTrajectory", "synthetic_trajectory",
    "Corridor", "PathSegments",
    "World", "Scenario", "ScenarioError", "default_scenario", "load_scenario", "save_scenario",
    "trilaterate", "triangulate_bearings", "StereoCalibration", "RectifiedCamera", "StereoMatcher",
    "navigation", "runner",
]
