"""Deorbit stage (patent step 103): forecast, two-body estimate, SQP correction under J2."""

from ovtraj.deorbit.inputs import DeorbitInput, EntryRegion, deorbit_input
from ovtraj.deorbit.result import DeorbitResult
from ovtraj.deorbit.stage import solve_deorbit

__all__ = ["DeorbitInput", "DeorbitResult", "EntryRegion", "deorbit_input", "solve_deorbit"]
