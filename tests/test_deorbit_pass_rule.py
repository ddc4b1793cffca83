"""Which pass the deorbit takes: within a cost bound of the tangential impulse, else the next.

The design below sits where the first pass in the entry region slips before the
preparation orbit begins as the separation delay grows: without the rule its burn is
pinned at the orbit's start and steered radially, and dV_total climbs by ~110 m/s within
0.3 h of t_dsp (a cliff no surrogate follows); with it the mission waits for the next pass
and the cost stays where it was.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from ovtraj.config import scenario_from_dict
from ovtraj.deorbit import deorbit_input
from ovtraj.deorbit.stage import burn_estimate
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import MissionContext, MissionDesign, evaluate

H_P0, H_DP = 319.09, 379.75
DELAYS_H = tuple(np.round(np.arange(10.0, 10.51, 0.05), 2))  # the benchmark's small step
PASS_STEP_H = 12.0  # entry passes of the region are a day or more apart


def _context(scenario, margin: float | None) -> MissionContext:
    data = scenario.resolved()
    data["deorbit"]["solver"]["pass_cost_margin_mps"] = margin
    changed = scenario_from_dict(data, "pass rule test")
    return MissionContext(changed, find_launch_fit(scenario))


@pytest.fixture(scope="module")
def flown(scenario):
    """Each delay's record with the shipped rule and with no cost bound."""
    shipped = MissionContext(scenario, find_launch_fit(scenario))
    unbounded = _context(scenario, None)
    return {
        "shipped": [evaluate(shipped, MissionDesign(H_P0, H_DP, t)) for t in DELAYS_H],
        "unbounded": [evaluate(unbounded, MissionDesign(H_P0, H_DP, t)) for t in DELAYS_H],
    }


def test_the_deorbit_cost_is_continuous_or_a_declared_pass_change(flown):
    records = flown["shipped"]
    assert all(r.feasible for r in records)
    for before, after in itertools.pairwise(records):
        dv_change = abs(after.dv_total_mps - before.dv_total_mps)
        t_change_h = abs(after.t_total_s - before.t_total_s) / 3600.0
        assert dv_change < 1.0 or t_change_h > PASS_STEP_H, (before.design, after.design)
    # The delays span the change of pass: the later ones wait two days more, at the same
    # minimum impulse (its two-body value at the shallowest entry angle, plus J2's < 1 m/s).
    waits = [r.t_total_s / 3600.0 for r in records]
    assert max(waits) - min(waits) > PASS_STEP_H
    impulses = [r.results.deorbit.dv_mps for r in records]
    assert max(impulses) - min(impulses) < 1.0


def test_every_pass_taken_is_within_its_cost_bound(flown, scenario):
    margin = scenario.deorbit.solver.pass_cost_margin_mps
    assert margin is not None and margin <= 2.0
    for record in flown["shipped"]:
        deorbit = record.results.deorbit
        inp = deorbit_input(
            scenario, state0=record.results.transfer.final_state, epoch=deorbit.epoch
        )
        cheapest = burn_estimate(inp, inp.state0, inp.entry.fpa_max_rad).dv_mps
        assert deorbit.dv_mps <= cheapest + margin + 0.1  # the pass's radius, not the start's
        assert math.degrees(deorbit.entry_fpa_rad) == pytest.approx(
            scenario.deorbit.entry.fpa_max_deg, abs=1e-3
        )


def test_without_the_bound_the_first_pass_is_taken_at_any_price(flown):
    # The cliff the rule removes: the same designs, the first pass at any cost.
    records = flown["unbounded"]
    impulses = np.array([r.results.deorbit.dv_mps for r in records])
    radial = np.array([abs(r.results.deorbit.dv_rsw_mps[0]) for r in records])
    assert impulses.max() - impulses.min() > 50.0
    assert radial.max() > 50.0
    jumps = [
        abs(b.dv_total_mps - a.dv_total_mps)
        for a, b in itertools.pairwise(records)
        if abs(b.t_total_s - a.t_total_s) < 3600.0
    ]
    assert max(jumps) > 10.0
