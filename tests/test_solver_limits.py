"""Every solver stops at its iteration limit and at its wall-time limit.

A tiny limit from the config must make the solve return its normal unconverged or
infeasible result, quickly, with a reason that names the config key of the limit; the
shipped limits must leave the shipped results alone (the stage tests check those). No
test here times a solve: the elapsed-time bounds only prove that nothing hangs.
"""

from __future__ import annotations

import copy
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.config import scenario_from_dict
from ovtraj.deadline import Deadline, TimeLimitReached
from tests.conftest import DEFAULT_SCENARIO, REPO

CASES = REPO / "configs" / "cases"
NO_HANG_S = 60.0  # generous: each limited solve below takes well under a second here
runner = CliRunner()


def _scenario(section: tuple[str, ...], **changes: Any):
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    node = data
    for part in section:
        node = node[part]
    node.update(changes)
    return scenario_from_dict(data, "test")


def _case(name: str, section: str, **changes: Any) -> dict[str, Any]:
    data = yaml.safe_load((CASES / name).read_text(encoding="utf-8"))
    data[section].update(changes)
    return copy.deepcopy(data)


class _Clock:
    def __enter__(self) -> _Clock:
        self.start = time.perf_counter()
        return self

    def __exit__(self, *exc: object) -> None:
        self.elapsed = time.perf_counter() - self.start


# --------------------------------------------------------------------------- the helper


def test_deadline_names_its_key_and_stays_reached():
    deadline = Deadline(1e-9, "rendezvous.time_limit_s")
    time.sleep(0.001)
    assert deadline.expired() and deadline.reached and deadline.remaining_s() == 0.0
    assert deadline.reason(12) == "rendezvous.time_limit_s = 1e-09 s reached after 12 iterations"
    assert deadline.reason() == "rendezvous.time_limit_s = 1e-09 s reached"
    with pytest.raises(TimeLimitReached, match="after 3 passes"):
        deadline.check(3, "passes")
    with pytest.raises(StopIteration):
        deadline.stop_if_expired()


def test_an_unlimited_deadline_never_passes_and_a_limit_must_be_positive():
    deadline = Deadline.unlimited()
    assert not deadline.expired() and deadline.remaining_s() == float("inf")
    deadline.check()
    deadline.stop_if_expired()
    assert not Deadline(3600.0, "x").expired()
    with pytest.raises(ValueError, match="x must be > 0 s"):
        Deadline(0.0, "x")


def test_nsga2_ends_at_the_deadline_or_the_generations():
    from ovtraj.optimize import nsga2_front

    def model(units):
        return np.column_stack([units[:, 0], 1.0 - units[:, 0] + units[:, 1]]), None

    designs, _, info = nsga2_front(
        model, 2, 2, population=8, generations=5, seed=1, deadline=Deadline(3600.0, "x")
    )
    assert len(designs) and info["reason"] is None and info["evaluations"] == 8 * 5
    with _Clock() as clock:
        designs, values, info = nsga2_front(
            model,
            2,
            2,
            population=8,
            generations=10**6,
            seed=1,
            deadline=Deadline(1e-6, "mission.optimize.time_limit_s"),
        )
    assert designs.shape == (0, 2) and values.shape == (0, 2)
    assert info["time_limit_reached"] is True
    assert info["reason"].startswith("NSGA-II stopped: mission.optimize.time_limit_s = 1e-06 s")
    assert clock.elapsed < NO_HANG_S


# --------------------------------------------------------------------------- rendezvous


def test_rendezvous_stops_at_its_time_limit():
    from ovtraj.rendezvous import rendezvous_input, solve_rendezvous

    with _Clock() as clock:
        result = solve_rendezvous(rendezvous_input(_scenario(("rendezvous",), time_limit_s=1e-6)))
    assert result.feasible is False
    assert result.reason.startswith(
        "J2 correction stopped: rendezvous.time_limit_s = 1e-06 s reached after "
    )
    assert clock.elapsed < NO_HANG_S


def test_rendezvous_stops_at_its_iteration_limit():
    from ovtraj.rendezvous import rendezvous_input, solve_rendezvous

    result = solve_rendezvous(rendezvous_input(_scenario(("rendezvous",), max_iterations=1)))
    assert result.feasible is False and result.iterations == 1
    assert "rendezvous.max_iterations = 1 reached" in result.reason


def test_the_cli_exits_1_when_the_rendezvous_runs_out_of_time(tmp_path: Path):
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["rendezvous"]["time_limit_s"] = 1e-6
    path = tmp_path / "hurried.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["rendezvous", str(path), "--json"])
    assert result.exit_code == 1
    row = json.loads(result.stdout)
    assert row["feasible"] is False and "rendezvous.time_limit_s" in row["reason"]
    data["rendezvous"]["time_limit_s"] = 0.0
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    bad = runner.invoke(app, ["rendezvous", str(path), "--json"])
    assert bad.exit_code == 2 and "rendezvous.time_limit_s = 0.0: out of range" in bad.stderr


# --------------------------------------------------------------------------- deorbit


def test_deorbit_stops_at_its_time_limit():
    from ovtraj.deorbit.inputs import deorbit_input
    from ovtraj.deorbit.stage import solve_deorbit

    with _Clock() as clock:
        result = solve_deorbit(deorbit_input(_scenario(("deorbit", "solver"), time_limit_s=1e-6)))
    assert result.feasible is False
    assert "deorbit.solver.time_limit_s = 1e-06 s reached" in result.reason
    assert clock.elapsed < NO_HANG_S


def test_deorbit_sqp_stops_at_its_iteration_limit():
    from ovtraj.deorbit.inputs import deorbit_input
    from ovtraj.deorbit.stage import solve_deorbit

    # Two SLSQP iterations already meet the constraints here, but not the minimum impulse:
    # a correction stopped by its limit is not accepted.
    result = solve_deorbit(deorbit_input(_scenario(("deorbit", "solver"), max_iterations=2)))
    assert result.feasible is False
    assert "SLSQP stopped: deorbit.solver.max_iterations = 2 reached" in result.reason


# --------------------------------------------------------------------------- reentry


def test_reentry_guidance_stops_at_its_time_limit():
    from ovtraj.reentry.inputs import reentry_input
    from ovtraj.reentry.stage import solve_reentry

    with _Clock() as clock:
        result = solve_reentry(reentry_input(_scenario(("reentry", "guidance"), time_limit_s=1e-6)))
    assert result.feasible is False and "time_limit" in result.flags
    assert result.reason.startswith(
        "guidance stopped: reentry.guidance.time_limit_s = 1e-06 s reached after "
    )
    assert clock.elapsed < NO_HANG_S


def test_reentry_newton_stops_at_its_iteration_limit():
    from ovtraj.reentry.inputs import reentry_input
    from ovtraj.reentry.stage import solve_reentry

    scenario = _scenario(("reentry", "guidance"), newton_iterations=1, newton_tolerance_km=1e-6)
    result = solve_reentry(reentry_input(scenario))
    assert result.feasible is False and "iteration_limit" in result.flags
    assert "reentry.guidance.newton_iterations = 1 reached" in result.reason


# --------------------------------------------------------------------------- optimal entry


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"time_limit_s": 1e-6}, "solver.time_limit_s = 1e-06 s reached while flying"),
        ({"time_limit_s": 0.05}, "solver.time_limit_s = 0.05 s reached"),
        ({"max_iterations": 3}, "solver.max_iterations = 3 reached (ipopt: Maximum_Iter"),
        ({"backend": "slsqp", "max_iterations": 2}, "solver.max_iterations = 2 reached (slsqp"),
        ({"backend": "trust-constr", "time_limit_s": 0.05}, "solver.time_limit_s = 0.05 s"),
    ],
)
def test_optimal_entry_stops_at_its_limits(changes, expected):
    from ovtraj.studies.optimal_entry import optimal_entry_from_dict, solve_optimal_entry

    data = _case("suborbital_return.yaml", "solver", **changes)
    with _Clock() as clock:
        result = solve_optimal_entry(optimal_entry_from_dict(data))
    assert result.converged is False
    assert expected in result.reason
    assert all(np.isfinite(v) for v in (result.range_km, result.final_time_s))
    assert clock.elapsed < NO_HANG_S


def test_the_cli_exits_1_when_the_optimal_entry_runs_out_of_time(tmp_path: Path):
    data = _case("suborbital_return.yaml", "solver", time_limit_s=1e-6)
    path = tmp_path / "hurried.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["optimal-entry", str(path), "--json", "--out", str(tmp_path)])
    assert result.exit_code == 1, result.output
    row = json.loads(result.stdout)
    assert row["converged"] is False and "solver.time_limit_s" in row["reason"]


# --------------------------------------------------------------------------- manoeuvre


def test_maneuver_search_stops_at_its_time_limit():
    from ovtraj.studies.maneuver import maneuver_from_dict, solve_maneuver

    data = _case("upper_stage_rendezvous.yaml", "optimizer", time_limit_s=1e-6)
    with _Clock() as clock:
        result = solve_maneuver(maneuver_from_dict(data))
    assert result.converged is False and result.burns == []  # no finite burns tried
    assert result.reason.startswith(
        "search stopped: optimizer.time_limit_s = 1e-06 s reached after 0 generations"
    )
    assert clock.elapsed < NO_HANG_S


def test_scipy_de_stops_at_its_time_limit():
    from ovtraj.studies.maneuver.de import scipy_de

    def evaluate(x):
        return x.sum(axis=1), np.zeros((len(x), 1))

    deadline = Deadline(1e-6, "optimizer.time_limit_s")
    time.sleep(0.001)
    result = scipy_de(
        evaluate,
        np.zeros(2),
        np.ones(2),
        n_constraints=1,
        population_per_variable=5,
        scale_factor=0.5,
        crossover_probability=0.5,
        generations=10**6,
        seed=1,
        deadline=deadline,
    )
    assert result.generations == 1
    assert result.limit == "optimizer.time_limit_s = 1e-06 s reached after 1 generations"


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"time_limit_s": 1e-6}, "finite burns stopped: finite_burn.time_limit_s = 1e-06 s"),
        ({"max_iterations": 1}, "finite burns stopped: finite_burn.max_iterations = 1 reached"),
    ],
)
def test_finite_burns_stop_at_their_limits(changes, expected):
    from ovtraj.studies.maneuver import maneuver_from_dict, solve_maneuver

    data = _case("upper_stage_rendezvous.yaml", "finite_burn", **changes)
    data["optimizer"]["generations"] = 150  # a feasible impulse plan, quickly
    result = solve_maneuver(maneuver_from_dict(data))
    assert result.converged is False
    assert result.reason.startswith(expected)


# --------------------------------------------------------------------------- deorbit burn


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"time_limit_s": 1e-6}, "guidance.time_limit_s = 1e-06 s reached after 1 iterations"),
        ({"max_iterations": 1}, "guidance.max_iterations = 1 reached: the entry u error"),
    ],
)
def test_deorbit_burn_iteration_stops_at_its_limits(changes, expected):
    from ovtraj.studies.deorbit_burn import deorbit_burn_from_dict, solve_deorbit_burn

    result = solve_deorbit_burn(
        deorbit_burn_from_dict(_case("shuttle_deorbit.yaml", "guidance", **changes))
    )
    assert result.converged is False and result.iterations == 1
    assert result.reason.startswith(expected)


# --------------------------------------------------------------------------- launch


def _quick_launch(**local: Any):
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["genetic"].update(population=6, generations=2)
    data["launch"]["local"].update(local)
    return data


def test_launch_ga_stops_at_its_time_limit():
    from ovtraj.launch import launch_input, solve_launch

    data = _quick_launch()
    data["launch"]["genetic"].update(generations=10**4, time_limit_s=1e-6)
    with _Clock() as clock:
        result = solve_launch(launch_input(scenario_from_dict(data)))
    assert result.feasible is False
    assert result.reason.startswith("genetic search stopped: launch.genetic.time_limit_s = 1e-06 s")
    assert [p.name for p in result.phases] == ["genetic"]  # no local phase after it
    assert clock.elapsed < NO_HANG_S


def test_launch_local_phase_stops_at_its_time_limit():
    from ovtraj.launch import launch_input, solve_launch

    data = _quick_launch(time_limit_s=1e-6)
    result = solve_launch(launch_input(scenario_from_dict(data)))
    assert result.feasible is False
    assert result.reason.startswith("slsqp stopped: launch.local.time_limit_s = 1e-06 s reached")
    assert [p.name for p in result.phases] == ["genetic", "slsqp"]
