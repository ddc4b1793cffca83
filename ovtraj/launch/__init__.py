"""Air-launch stage (patent step 101): maximum-payload ascent and the launch fit."""

from ovtraj.launch.inputs import LaunchInput, TargetPlane, launch_input
from ovtraj.launch.result import LaunchResult
from ovtraj.launch.stage import solve_launch

__all__ = ["LaunchInput", "LaunchResult", "TargetPlane", "launch_input", "solve_launch"]
