"""Prefect-native caching: one cache policy on every task, keyed on the inputs
and the code version; the run store stays the source of truth.

For every flow, an unchanged code version is served from the cache (or from the store,
which the flows consult first) and a changed one computes again. The code change is
simulated by patching ``ovtraj.version.code_version``, which the cache policy and the
flows read when they run; the tasks run in the test's process (serial or thread runners)
so that the patch applies to them. What ran is counted where it runs: the library call
inside each task is wrapped by a counter (the real call still runs).
"""

from __future__ import annotations

import copy
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.runs import execute
from ovtraj.target_sources import load_scenario
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario, shorten_launch_fit

CODE_A, CODE_B = "cache-test-a", "cache-test-b"
CASE = REPO / "configs" / "cases" / "shuttle_deorbit.yaml"


def _set_code(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    import importlib

    monkeypatch.setattr(importlib.import_module("ovtraj.version"), "code_version", lambda: value)


def _count(monkeypatch: pytest.MonkeyPatch, module: Any, name: str, calls: Counter) -> None:
    """Wrap ``module.name`` so that each call is counted under ``name`` (it still runs)."""
    real = getattr(module, name)

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls[name] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)


def _scenario(tmp: Path, **doe: Any) -> dict[str, Any]:
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(store=str(tmp / "runs"), task_runner="serial", **doe)
    return data


def _write(tmp: Path, data: dict[str, Any], name: str = "scenario.yaml") -> str:
    build_scenario(copy.deepcopy(data))
    path = tmp / name
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


# -- the policy ------------------------------------------------------------------------------
def test_every_task_has_the_one_cache_policy_and_no_code_parameter():
    import inspect

    from prefect import Task

    import tasks.deorbit_monte_carlo
    import tasks.doe
    import tasks.launch
    import tasks.pipeline
    import tasks.rendezvous
    from tasks.common import CACHE_POLICY, EXPIRATION

    modules = (tasks.doe, tasks.launch, tasks.rendezvous, tasks.pipeline, tasks.deorbit_monte_carlo)
    found = [value for m in modules for value in vars(m).values() if isinstance(value, Task)]
    assert {t.name for t in found} == {
        "mission-batch",
        "launch-point",
        "rendezvous",
        "deorbit-mc-batch",
        "fit-surrogates",
        "surrogate-front",
    }
    for task in found:
        assert task.cache_policy is CACHE_POLICY, task.name
        assert task.persist_result and task.cache_expiration == EXPIRATION, task.name
        assert task.timeout_seconds and task.timeout_seconds > 0, task.name
        parameters = inspect.signature(task.fn).parameters
        assert not {"code", "code_version"} & set(parameters), task.name


# -- rendezvous -------------------------------------------------------------------------------
def test_rendezvous_flow_recomputes_after_a_code_change_only(prefect_server, monkeypatch):
    import tasks.rendezvous
    from flows.rendezvous import rendezvous_flow

    calls: Counter = Counter()
    _count(monkeypatch, tasks.rendezvous, "solve_rendezvous", calls)
    _set_code(monkeypatch, CODE_A)
    first = rendezvous_flow(str(DEFAULT_SCENARIO))
    again = rendezvous_flow(str(DEFAULT_SCENARIO))
    assert calls["solve_rendezvous"] == 1 and again == first  # served from the cache
    _set_code(monkeypatch, CODE_B)
    rendezvous_flow(str(DEFAULT_SCENARIO))
    assert calls["solve_rendezvous"] == 2  # the code changed: solved again


# -- launch fit ---------------------------------------------------------------------------------
def test_launch_fit_flow_recomputes_after_a_code_change_only(prefect_server, tmp_path, monkeypatch):
    from flows.launch_fit import launch_fit_flow

    data = _scenario(tmp_path)
    data["name"] = "launch-fit-cache-test"
    shorten_launch_fit(data)
    config = _write(tmp_path, data)
    _set_code(monkeypatch, CODE_A)
    first = launch_fit_flow(config, out=str(tmp_path / "a"), runner="threads")
    again = launch_fit_flow(config, out=str(tmp_path / "a2"), runner="threads")
    _set_code(monkeypatch, CODE_B)
    changed = launch_fit_flow(config, out=str(tmp_path / "b"), runner="threads")
    assert first["cached_points"] == 0
    assert again["cached_points"] == again["solved_points"] == first["solved_points"]
    assert again["payload_kg"] == first["payload_kg"]
    assert changed["cached_points"] == 0 and changed["solved_points"] == first["solved_points"]
    # What the flow stores: the fit of the configured range, payload falling with altitude.
    assert first["points"] == 5 and np.all(np.diff(np.array(first["payload_kg"])) < 0.0)
    fit = LaunchFit.load(tmp_path / "a")
    assert fit.altitude_range_km == pytest.approx((280.0, 320.0))
    assert fit.launcher == load_scenario(Path(config)).launch.launcher.name


# -- DoE --------------------------------------------------------------------------------------
def test_doe_flow_recomputes_after_a_code_change_only(prefect_server, tmp_path, monkeypatch):
    from flows.doe import run_doe_flow

    config = _write(tmp_path, _scenario(tmp_path, samples=2, batch_size=1))
    _set_code(monkeypatch, CODE_A)
    before = execute.EVALUATIONS["count"]
    first = run_doe_flow(config=config)
    middle = execute.EVALUATIONS["count"]
    again = run_doe_flow(config=config)
    after = execute.EVALUATIONS["count"]
    _set_code(monkeypatch, CODE_B)
    changed = run_doe_flow(config=config)
    assert (middle - before, after - middle) == (2, 0)  # the store serves the same code
    assert again["run_id"] == first["run_id"]
    assert changed["run_id"] != first["run_id"]  # the code version is in the run id
    assert execute.EVALUATIONS["count"] - after == 2
    assert changed["status"] == "complete"


# -- deorbit Monte Carlo -------------------------------------------------------------------------
def test_deorbit_monte_carlo_flow_recomputes_after_a_code_change_only(
    prefect_server, tmp_path, monkeypatch
):
    from flows.deorbit_monte_carlo import deorbit_monte_carlo_flow
    from ovtraj.studies.deorbit_burn.montecarlo import SIMULATIONS

    data = yaml.safe_load(CASE.read_text(encoding="utf-8"))
    data["monte_carlo"].update(task_runner="threads", workers=1, store=str(tmp_path / "mc"))
    config = tmp_path / "case.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    arguments = {"config": str(config), "runs": 1, "batch_size": 1, "strategies": [2]}
    _set_code(monkeypatch, CODE_A)
    before = SIMULATIONS["runs"]
    first = deorbit_monte_carlo_flow(**arguments)
    middle = SIMULATIONS["runs"]
    again = deorbit_monte_carlo_flow(**arguments)
    after = SIMULATIONS["runs"]
    _set_code(monkeypatch, CODE_B)
    changed = deorbit_monte_carlo_flow(**arguments)
    assert (middle - before, after - middle, SIMULATIONS["runs"] - after) == (1, 0, 1)
    assert again["run_id"] == first["run_id"] != changed["run_id"]
    assert changed["status"] == "complete"


# -- surrogate, optimize, mission (one small pipeline) -------------------------------------------
def _pipeline_data(tmp: Path) -> dict[str, Any]:
    data = _scenario(tmp, samples=10, batch_size=5)
    data["mission"]["verify"].update(points_per_iteration=1, max_iterations=1, budget=1)
    data["mission"]["surrogate"].update(
        regressors=["RBF"], classifiers=["logistic"], folds=2, min_training_samples=4
    )
    data["mission"]["optimize"].update(population=16, generations=5)
    return data


@pytest.fixture(scope="module")
def pipeline(prefect_server, tmp_path_factory):
    """The mission flow with code A, once; then what each step computed again."""
    from flows.pipeline import mission_flow

    tmp = tmp_path_factory.mktemp("cache-pipeline")
    config = _write(tmp, _pipeline_data(tmp))
    with pytest.MonkeyPatch.context() as patch:
        _set_code(patch, CODE_A)
        calls = _pipeline_work(patch)
        before = execute.EVALUATIONS["count"]
        # one round of one point: whether it converges is not this module's business
        first = mission_flow(config=config, require_converged=False)
        evaluations = execute.EVALUATIONS["count"] - before
    return {
        "config": config,
        "tmp": tmp,
        "first": first,
        "calls": calls,
        "evaluations": evaluations,
    }


def _counted(monkeypatch: pytest.MonkeyPatch) -> Counter:
    import tasks.pipeline
    from ovtraj.pipeline import planning

    calls: Counter = Counter()
    _count(monkeypatch, tasks.pipeline, "fit_step", calls)
    _count(monkeypatch, tasks.pipeline, "front_step", calls)
    _count(monkeypatch, planning, "write_mission_plan", calls)
    return calls


def _pipeline_work(monkeypatch: pytest.MonkeyPatch) -> Counter:
    """Count the mission flow's work beyond the batches: a surrogate fit, an NSGA-II run
    (not a load of a stored one) and a plan written (the flow runs the library's
    driver, its fits and fronts stored in the run and reused by content)."""
    from ovtraj.pipeline import drive, steps

    calls: Counter = Counter()
    _count(monkeypatch, steps, "fit_mission_surrogates", calls)
    _count(monkeypatch, steps, "surrogate_front", calls)
    _count(monkeypatch, drive, "write_mission_plan", calls)
    return calls


def test_mission_flow_recomputes_after_a_code_change_only(pipeline, monkeypatch):
    from flows.pipeline import mission_flow

    first = pipeline["first"]
    assert pipeline["evaluations"] == 10 + first["real_evaluations"]["infill"]
    assert pipeline["calls"]["write_mission_plan"] == 1
    assert pipeline["calls"]["fit_mission_surrogates"] >= 1
    calls = _pipeline_work(monkeypatch)
    _set_code(monkeypatch, CODE_A)
    before = execute.EVALUATIONS["count"]
    plan = Path(first["plan_json"]).read_bytes()
    again = mission_flow(config=pipeline["config"], require_converged=False)
    assert execute.EVALUATIONS["count"] == before  # the store serves the batches
    # fits and fronts loaded from the run, not computed; the plan written again, the same
    assert calls["fit_mission_surrogates"] == 0 and calls["surrogate_front"] == 0
    assert calls["write_mission_plan"] == 1 and Path(again["plan_json"]).read_bytes() == plan
    assert again == first
    _set_code(monkeypatch, CODE_B)
    changed = mission_flow(config=pipeline["config"], require_converged=False)
    assert changed["doe_run"] != first["doe_run"]
    assert execute.EVALUATIONS["count"] - before == 10 + changed["real_evaluations"]["infill"]
    assert calls["fit_mission_surrogates"] >= 1 and calls["surrogate_front"] >= 1
    assert calls["write_mission_plan"] == 2


def test_surrogate_flow_recomputes_after_a_code_change_only(pipeline, monkeypatch):
    from flows.surrogate import surrogate_flow

    store = str(Path(pipeline["tmp"]) / "runs")
    run_id = pipeline["first"]["doe_run"]
    calls = _counted(monkeypatch)
    _set_code(monkeypatch, CODE_A)
    # The mission flow's rounds stored their fits without plots (it draws only the last
    # round's): the surrogate flow, which shows the parity plots, fits once with them, then
    # is served.
    drawn = surrogate_flow(run_id, pipeline["config"], store)
    assert calls["fit_step"] == 1
    assert sorted(p.name for p in Path(drawn["directory"]).glob("parity-*.png"))
    served = surrogate_flow(run_id, pipeline["config"], store)
    assert calls["fit_step"] == 1 and served == drawn
    _set_code(monkeypatch, CODE_B)
    refitted = surrogate_flow(run_id, pipeline["config"], store)
    assert calls["fit_step"] == 2 and refitted["fit_id"] != served["fit_id"]


def test_optimize_flow_recomputes_after_a_code_change_only(pipeline, monkeypatch):
    from flows.optimize import optimize_flow

    store = str(Path(pipeline["tmp"]) / "runs")
    run_id = pipeline["first"]["doe_run"]
    calls = _counted(monkeypatch)
    _set_code(monkeypatch, CODE_A)
    drawn = optimize_flow(run_id, pipeline["config"], store)  # with its plot: computed once
    computed = dict(calls)
    served = optimize_flow(run_id, pipeline["config"], store)
    assert calls == computed and served == drawn
    _set_code(monkeypatch, CODE_B)
    changed = optimize_flow(run_id, pipeline["config"], store)
    assert calls["front_step"] > computed["front_step"]
    assert changed["front_id"] != served["front_id"]


@pytest.mark.parametrize("toplevel", [None, "/somebody/elses/repository"])
def test_an_installed_copy_is_versioned_by_its_sources(monkeypatch, toplevel):
    """Outside a git checkout of its own (a wheel in site-packages, possibly inside another
    repository) the code version is the package version and a digest of its sources."""
    import ovtraj
    from ovtraj import version

    def git(*args):
        if toplevel is None:
            return None
        return toplevel + "\n" if "--show-toplevel" in args else "0123456789ab\n"

    monkeypatch.setattr(version, "_git", git)
    version.code_version.cache_clear()
    try:
        installed = version.code_version()
    finally:
        version.code_version.cache_clear()
    assert installed == f"{ovtraj.__version__}+s{version.source_digest()}"


def test_the_source_digest_moves_with_any_source(tmp_path):
    from ovtraj import version

    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    (tmp_path / "data.yaml").write_text("not a source\n")
    first = version.source_digest(tmp_path)
    assert len(first) == 12 and int(first, 16) >= 0
    (tmp_path / "data.yaml").write_text("changed, still not a source\n")
    assert version.source_digest(tmp_path) == first
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    changed = version.source_digest(tmp_path)
    assert changed != first
    (tmp_path / "sub" / "b.py").rename(tmp_path / "sub" / "c.py")
    assert version.source_digest(tmp_path) not in (first, changed)
