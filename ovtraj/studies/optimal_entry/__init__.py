"""Pseudospectral optimal lifting entry (seed 001).

Legendre-Gauss collocation (the seed's Gauss pseudospectral method) or Legendre-Gauss-
Radau, one or several segments, normalised energy or time as the independent variable,
IPOPT through CasADi with exact derivatives or a scipy fallback; problems are posed by
YAML (``configs/cases/suborbital_return.yaml`` is the seed's published case). See
``docs/optimal_entry.md``.
"""

from ovtraj.studies.optimal_entry.feasibility import FeasibilityReport
from ovtraj.studies.optimal_entry.problem import (
    EntryProblem,
    load_optimal_entry,
    optimal_entry_from_dict,
)
from ovtraj.studies.optimal_entry.result import OptimalEntryResult, write_histories
from ovtraj.studies.optimal_entry.solve import solve_optimal_entry

__all__ = [
    "EntryProblem",
    "FeasibilityReport",
    "OptimalEntryResult",
    "load_optimal_entry",
    "optimal_entry_from_dict",
    "solve_optimal_entry",
    "write_histories",
]
