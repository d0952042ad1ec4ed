"""Precision reliability of multi-axis machine tools (Hu, Wang & Ma 2023, made exact).

The machine model (:mod:`reliability.machine`, :mod:`reliability.kinematics`), FOSM
reliability (:mod:`reliability.fosm`), pose sets (:mod:`reliability.poses`), the
Monte-Carlo sampling engine (:mod:`reliability.sampling`) with its results and
statistics, the continuous worst-pose search (:mod:`reliability.worst_case`), Monte-Carlo
at given poses (:mod:`reliability.pose_sampling`) and rare-event estimates
(:mod:`reliability.rare`).
"""

from .errors import MachineDescriptionError
from .fosm import FosmResult, fosm
from .machine import (COMPONENTS, OUTPUTS, Axis, CostCoefficients, Machine, hobbing_machine,
                      load_machine, machine_from_dict)
from . import rare
from .pose_sampling import PoseSamplingResult, sample_at_poses
from .poses import random_poses, workspace_grid
from .results import GridExperimentResult, RandomPoseResult
from .sampling import GridExperiment, sample_random_poses
from .system import SystemReliability, system_reliability, worst_system_reliability

__all__ = ["COMPONENTS", "OUTPUTS", "Axis", "CostCoefficients", "FosmResult",
           "GridExperiment", "GridExperimentResult", "Machine", "MachineDescriptionError",
           "PoseSamplingResult", "RandomPoseResult", "SystemReliability", "fosm",
           "hobbing_machine", "load_machine", "machine_from_dict", "random_poses", "rare",
           "sample_at_poses", "sample_random_poses", "system_reliability", "workspace_grid",
           "worst_system_reliability"]
