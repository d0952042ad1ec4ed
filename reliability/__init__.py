"""Precision reliability of multi-axis machine tools (Hu, Wang & Ma 2023, made exact).

The machine model (:mod:`reliability.machine`, :mod:`reliability.kinematics`), FOSM
reliability (:mod:`reliability.fosm`), pose sets (:mod:`reliability.poses`) and the
Monte-Carlo sampling engine (:mod:`reliability.sampling`).
"""

from .machine import (COMPONENTS, OUTPUTS, Axis, CostCoefficients, Machine,
                      MachineDescriptionError, hobbing_machine, load_machine,
                      machine_from_dict)

__all__ = ["COMPONENTS", "OUTPUTS", "Axis", "CostCoefficients", "Machine",
           "MachineDescriptionError", "hobbing_machine", "load_machine", "machine_from_dict"]
