"""One scenario per launch day.

Day ``d`` of a window is the scenario launched ``d`` days after its own
``launch.launch_date_utc``. What moves with the day, and what does not:

- ``launch.launch_date_utc``: the day; every time of the mission counts from its 0 h;
- ``deorbit.preparation_orbit.epoch_utc`` (the stand-alone deorbit's start, "two days
  after launch"; the mission chain hands the deorbit the vehicle's own state) moves by the
  same days, so each day's file means what the scenario's does;
- ``epoch_utc`` and the target do not: the target's elements are given at the campaign
  epoch (a TLE or OMM at its own), and the chain propagates the same object to each day
  (``ovtraj.launch.inputs.target_plane_at``, ``MissionContext``). Moving the epoch with
  the elements unchanged would put another target in the sky every day.

Day 0 is the scenario itself, resolved: its DoE run is the one ``ovtraj pipeline`` makes.
"""

from __future__ import annotations

import datetime

from ovtraj.astro.epoch import Epoch
from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.units import S_PER_DAY

__all__ = ["day_scenario", "launch_date"]


def launch_date(base: Scenario, offset_days: int) -> str:
    """The launch date (``YYYY-MM-DD``) ``offset_days`` after the scenario's."""
    first = datetime.date.fromisoformat(base.launch.launch_date_utc)
    return (first + datetime.timedelta(days=offset_days)).isoformat()


def day_scenario(base: Scenario, offset_days: int) -> Scenario:
    """The scenario launched ``offset_days`` after ``base`` (module notes), validated as
    any scenario is (``ConfigError`` naming the day)."""
    if base.launch is None:
        raise ValueError("the scenario has no launch section")
    data = base.resolved()
    if offset_days == 0:  # the scenario itself, not a re-formatted copy of it
        return scenario_from_dict(data, "day 0 of the window")
    data["launch"]["launch_date_utc"] = launch_date(base, offset_days)
    deorbit = data.get("deorbit")
    if deorbit is not None:
        start = Epoch.from_iso(deorbit["preparation_orbit"]["epoch_utc"])
        later = start.plus_seconds(offset_days * S_PER_DAY)
        deorbit["preparation_orbit"]["epoch_utc"] = later.iso()
    return scenario_from_dict(data, f"day {offset_days} of the window")
