"""Every scene table by name."""

from __future__ import annotations

from .tables_allostery import AllosterySpec
from .tables_learning import LearningSpec, NetworkSpec, SolverSpec, TaskSpec
from .tables_mechanism import MechanismSpec
from .tables_physics import (
    AccuracySpec,
    ContinuumSpec,
    DynamicsSpec,
    ExportSpec,
    PhysicalTimeSpec,
    ReportSpec,
    StabilitySpec,
)

_TABLES: dict[str, type] = {
    "network": NetworkSpec,
    "task": TaskSpec,
    "learning": LearningSpec,
    "solver": SolverSpec,
    "continuum": ContinuumSpec,
    "dynamics": DynamicsSpec,
    "stability": StabilitySpec,
    "accuracy": AccuracySpec,
    "physical_time": PhysicalTimeSpec,
    "allostery": AllosterySpec,
    "mechanism": MechanismSpec,
    "export": ExportSpec,
    "report": ReportSpec,
}
