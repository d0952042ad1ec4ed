"""Precision reliability of multi-axis machine tools (Hu, Wang & Ma 2023, made exact).

The package lives in rooms by idea, each importing only the rooms below it:

- :mod:`reliability.basics`: exceptions, input checks, random streams, statistics, display,
  ties, memory chunks and result files;
- :mod:`reliability.model`: the machine description, kinematics, poses, ISO names, error
  profiles, correlation and error draws;
- :mod:`reliability.first_order`: FOSM (Eqs. 19–23), the exact linear probability, system
  reliability and the worst pose over the workspace (search and certificate);
- :mod:`reliability.sampling`: the grid experiment (Sec. 5.3), Monte-Carlo at poses, rare
  events, the machine yield and the verification of an allocation;
- :mod:`reliability.acceptance`: ISO 230 acceptance tests on the model;
- :mod:`reliability.measured`: measurement files, simulated measurements and the
  identification of a built machine's errors;
- :mod:`reliability.compensation`: compensation tables, their files and the error a
  compensated machine keeps;
- :mod:`reliability.interop`: the machine as an OpenTURNS and a SALib model (the optional
  ``interop`` extra, imported only when used).

The names most users need are exported here.
"""

from .basics.errors import MachineDescriptionError
from .compensation.compensation_files import write_compensation
from .compensation.tables import CompensationTables, compensation_tables, read_compensation
from .first_order.fosm import FosmResult, fosm
from .first_order.system_reliability import (SystemReliability, system_reliability,
                                             worst_system_reliability)
from .model.machine import COMPONENTS, OUTPUTS, Axis, CostCoefficients, Machine
from .model.machine_file import hobbing_machine, load_machine, machine_from_dict, machine_from_toml
from .measured.identification import Identification, identify, read_identification
from .measured.measurement_files import read_measurements
from .model.poses import random_poses, workspace_grid
from .sampling import rare_events as rare
from .sampling.experiment_results import GridExperimentResult, RandomPoseResult
from .sampling.grid_experiment import GridExperiment
from .sampling.pose_sampling import PoseSamplingResult, sample_at_poses, sample_random_poses

__all__ = ["COMPONENTS", "OUTPUTS", "Axis", "CompensationTables", "CostCoefficients",
           "FosmResult",
           "GridExperiment", "GridExperimentResult", "Identification", "Machine",
           "MachineDescriptionError",
           "PoseSamplingResult", "RandomPoseResult", "SystemReliability", "fosm",
           "hobbing_machine", "identify", "load_machine", "machine_from_dict",
           "machine_from_toml",
           "interop", "random_poses", "rare", "read_compensation", "read_identification",
           "read_measurements", "compensation_tables", "sample_at_poses",
           "sample_random_poses", "system_reliability", "workspace_grid",
           "worst_system_reliability", "write_compensation"]


def __getattr__(name):
    """``reliability.interop`` on first use: it brings scipy.stats, which plain use of the
    toolkit does not need at import."""
    if name == "interop":
        import importlib
        return importlib.import_module(".interop", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
