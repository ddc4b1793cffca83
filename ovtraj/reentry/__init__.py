"""Reentry stage (patent step 104): 3-DOF lifting entry guided to the runway."""

from ovtraj.reentry.inputs import EntryState, ReentryInput, reentry_input
from ovtraj.reentry.result import ReentryResult
from ovtraj.reentry.stage import solve_reentry

__all__ = ["EntryState", "ReentryInput", "ReentryResult", "reentry_input", "solve_reentry"]
