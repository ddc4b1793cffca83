"""Shared fixtures: the project's Earth model and the default scenario."""

from __future__ import annotations

import copy
import hashlib
import os
import socket
from pathlib import Path
from typing import Any

import pytest
import yaml

from ovtraj.astro.constants import EarthModel
from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.config.physical import default_earth
from ovtraj.mission.chain import MissionDesign
from ovtraj.target_sources import load_scenario

# Prefect must never try to reach the network from the test suite.
os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")

REPO = Path(__file__).resolve().parents[1]
# Keys the rendezvous result row (and `ovtraj rendezvous --json`) must carry.
REQUIRED_KEYS = {
    "dv1_mps",
    "dv2_mps",
    "transfer_time_s",
    "wait_time_s",
    "lead_angle_deg",
    "lead_angle_two_body_deg",
    "miss_distance_m",
    "feasible",
}
# Keys `ovtraj deorbit --json` must carry.
DEORBIT_KEYS = {
    "burn_epoch_utc",
    "dv_mps",
    "wait_time_s",
    "entry_lat_deg",
    "entry_lon_deg",
    "entry_fpa_deg",
    "entry_speed_mps",
    "entry_error_km",
    "feasible",
}
# Keys `ovtraj reentry --json` must carry.
REENTRY_KEYS = {
    "miss_distance_km",
    "flight_time_s",
    "max_heat_rate_kw_m2",
    "max_load_g",
    "max_dynamic_pressure_kpa",
    "terminal_altitude_km",
    "terminal_speed_mps",
    "feasible",
}
DEFAULT_SCENARIO = REPO / "configs" / "scenario.yaml"
# A feasible design of the shipped scenario (parking altitude [km], phasing-orbit apogee
# altitude [km], waiting time before the phasing manoeuvre [h]): its plan is the
# reference plan every plan, export, Monte Carlo and hostile-input test starts from.
FEASIBLE_DESIGN = MissionDesign(285.06, 326.96, 0.79)


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now (for a server a test starts)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def digest(directory: Path, pattern: str = "*.parquet") -> dict[str, str]:
    """SHA-256 of every file under ``directory`` matching ``pattern``, by relative path:
    two stores hold the same bytes when their digests are equal."""
    return {
        str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.rglob(pattern))
        if p.is_file()
    }


@pytest.fixture(scope="session")
def prefect_server(tmp_path_factory):
    """One temporary Prefect server for every flow test of the session.

    Its start costs 6-60 s on this machine (CPU-bound, varies with the VM's speed); one
    per module cost minutes of the suite's budget. Prefect's home (``PREFECT_HOME``, its
    default result storage) and the flows' task results (``OVTRAJ_PREFECT_RESULTS``,
    configs/orchestration.yaml ``results``) are folders of the session, never the
    user's ``~/.prefect`` or workspace. Yields them.
    """
    from prefect.settings import (
        PREFECT_HOME,
        PREFECT_RESULTS_LOCAL_STORAGE_PATH,
        temporary_settings,
    )
    from prefect.testing.utilities import prefect_test_harness

    from ovtraj.config.orchestration import RESULTS_ENV

    home = tmp_path_factory.mktemp("prefect-home")
    results = home / "task-results"
    before = os.environ.get(RESULTS_ENV)
    os.environ[RESULTS_ENV] = str(results)
    updates = {PREFECT_HOME: home, PREFECT_RESULTS_LOCAL_STORAGE_PATH: home / "storage"}
    try:
        with (
            temporary_settings(updates=updates),
            prefect_test_harness(server_startup_timeout=120),
        ):
            yield {"home": home, "results": results}
    finally:
        if before is None:
            os.environ.pop(RESULTS_ENV, None)
        else:
            os.environ[RESULTS_ENV] = before


@pytest.fixture(scope="session")
def earth() -> EarthModel:
    return default_earth()


@pytest.fixture(scope="session")
def scenario() -> Scenario:
    return load_scenario(DEFAULT_SCENARIO)


@pytest.fixture(scope="session")
def mission_context(scenario):
    """The shipped scenario with its reference launch fit (data/reference/launch_fit)."""
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.mission.chain import MissionContext

    fit = find_launch_fit(scenario)
    assert fit is not None, "the reference launch fit is missing (data/reference/launch_fit)"
    return MissionContext(scenario, fit)


@pytest.fixture(scope="session")
def reference_plan(mission_context, tmp_path_factory):
    """The plan of :data:`FEASIBLE_DESIGN` on the shipped scenario, built once per worker
    (a launch solve, the chain and the plan's own checks: seconds each time)."""
    from ovtraj.mission.plan_build import build_plan

    cache = tmp_path_factory.mktemp("reference-plan-launch-solves")
    source = {"run_id": "test", "front_index": 0}
    return build_plan(mission_context, FEASIBLE_DESIGN, source=source, launch_cache=cache)


@pytest.fixture(scope="session")
def reference_plan_file(reference_plan, tmp_path_factory) -> Path:
    """:func:`reference_plan` written as ``chosen.json`` (and its CSV) in a folder of its own."""
    from ovtraj.mission.plan_store import write_plan

    return write_plan(reference_plan, tmp_path_factory.mktemp("reference-plan"), "chosen")[0]


@pytest.fixture
def scenario_data() -> dict[str, Any]:
    """The default scenario as a fresh mutable mapping."""
    with open(DEFAULT_SCENARIO, encoding="utf-8") as fh:
        return copy.deepcopy(yaml.safe_load(fh))


def shorten_launch_fit(data: dict[str, Any]) -> dict[str, Any]:
    """A scenario's launch fit made quick, in place: five points (the fewest an order-1 fit
    takes), the reference (300 km) among them; a smaller GA, coarser steps, looser and
    shorter local phases: each point still feasible and the payload falling with altitude,
    in ~7 s a flow run here, not ~40 s. The mission section goes (its design bounds need
    the full fit range). Returns ``data``."""
    launch = data["launch"]
    launch["fit"].update(altitude_min_km=280.0, altitude_max_km=320.0, points=5, order=1)
    shorten_launch_search(launch)
    data.pop("mission")
    return data


def shorten_launch_search(launch: dict[str, Any]) -> dict[str, Any]:
    """A scenario's ``launch`` section searched quickly, in place: a smaller GA, coarser
    steps, looser and shorter local phases (the fit grid untouched). Returns ``launch``."""
    launch["genetic"].update(population=16, generations=6)
    launch["integration"].update(powered_step_s=4.0, coast_step_s=40.0)
    launch["local"].update(
        converged_residual=1.0,
        slsqp_ftol=1e-5,
        slsqp_max_iterations=30,
        trust_constr_max_iterations=5,
        stall_iterations=2,
        stall_payload_kg=0.1,
    )
    return launch


def build_scenario(data: dict[str, Any]) -> Scenario:
    return scenario_from_dict(data, "test")


def held_claim(run_dir: Path) -> tuple[int, int] | None:
    """(batch, pid) of a batch claim a live process holds now on a batch not stored yet
    (the tests that kill the process computing a batch)."""
    import re

    from ovtraj.store import locks

    for lock in sorted((run_dir / "locks").glob("batch-*.lock")):
        batch = int(lock.stem.split("-")[1])
        if (run_dir / "batches" / f"{batch}.json").exists() or not locks.held(lock):
            continue
        found = re.search(r"pid (\d+)", lock.read_text(encoding="utf-8"))
        if found:
            return batch, int(found.group(1))
    return None


def prefect_record(folder: Path, key: str) -> Path:
    """A task result record ``folder/key`` as Prefect writes one (its own ``ResultStore``
    on local storage), in a subprocess whose Prefect home is a folder beside ``folder``."""
    import subprocess
    import sys

    script = (
        "import sys\n"
        "from prefect.filesystems import LocalFileSystem\n"
        "from prefect.results import ResultStore\n"
        "store = ResultStore(result_storage=LocalFileSystem(basepath=sys.argv[1]))\n"
        "store.write({'run_id': '0123456789abcdef', 'batch': 0}, key=sys.argv[2])\n"
    )
    env = dict(os.environ, PREFECT_HOME=str(folder.parent / f"{folder.name}-prefect-home"))
    args = [sys.executable, "-c", script, str(folder), key]
    subprocess.run(args, check=True, timeout=300, env=env, capture_output=True)
    return folder / key


# Modules that take minutes (fresh installs, Prefect servers, every benchmark): run first.
# With `-n 2 --dist loadfile` a module is one unit of work, handed out in collection order;
# collected last (alphabetically: test_user_install), the longest ran alone at the end
# while the other worker had nothing left (15 min measured, the sum of the work ~27 min).
# test_tracking.py second: it builds the re-plan nights (replan_nights, ~70 s) that
# test_prefect_ui.py also uses, on the worker not installing; collected in alphabetical
# order the two met, and one worker waited ~50 s on the other's build.
LONG_MODULES = (
    "test_user_install.py",
    "test_tutorial.py",  # ~5 min: the tutorial's three pipelines, a flow run and services
    "test_tracking.py",
    "test_install.py",
    "test_benchmarks.py",
    "test_window.py",  # ~100 s: a 3-day scan and its flow; collected last it would end alone
)


# A test that uses one of these (directly or through another fixture) starts a server: the
# fast tier (-m "not slow") leaves it out, as README says.
SERVER_FIXTURES = frozenset({"prefect_server"})


def measured_slow_tests() -> set[str]:
    """The test ids tools/slow_tests.py chose from a measured run (tests/slow_tests.txt)."""
    listing = REPO / "tests" / "slow_tests.txt"
    if os.environ.get("OVTRAJ_SLOW_LISTING") == "off":  # tools/slow_tests.py: the other marks
        return set()
    lines = listing.read_text(encoding="utf-8").splitlines() if listing.is_file() else []
    return {line.split("#")[0].strip() for line in lines if line.split("#")[0].strip()}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> int:
        name = item.path.name
        return LONG_MODULES.index(name) if name in LONG_MODULES else len(LONG_MODULES)

    slow = measured_slow_tests()
    for item in items:
        if item.nodeid in slow or SERVER_FIXTURES.intersection(item.fixturenames):
            item.add_marker(pytest.mark.slow)
    items.sort(key=rank)  # stable: every module's own order is kept


# --- the re-plan nights shared by the tracking and UI tests ---------------------------------

REPLAN_NIGHTS = 3


def replan_config(folder: Path) -> Path:
    """The default scenario as a nightly re-plan made quick: a five-point launch fit over
    280-320 km (``shorten_launch_search``'s search), the parking altitude inside it, a
    12-sample DoE, two regressors and 3 folds, a short NSGA-II, one round of 3 infill points.
    The plan may fly M_load 1 kg from its front point: the short search's payloads are
    0.2-0.4 kg from the launch the plan solves (the shipped 0.1 kg refused the plan)."""
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["launch"]["fit"].update(altitude_min_km=280.0, altitude_max_km=320.0, points=5, order=1)
    shorten_launch_search(data["launch"])
    mission = data["mission"]
    mission["design_bounds"]["parking_altitude_km"].update(lower=285.0, upper=315.0)
    mission["doe"].update(samples=12, batch_size=6)
    mission["verify"].update(points_per_iteration=3, max_iterations=1, budget=3)
    mission["surrogate"].update(regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3)
    mission["optimize"].update(population=24, generations=20)
    mission["plan"]["front_tolerance"]["m_load_kg"] = 1.0
    path = folder / "nightly.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def replan_nights(tmp_path_factory: Any) -> dict[str, Any]:
    """Three nights of a drifting target re-planned into one store, as the nightly
    deployment runs them: ``tools/example_tle.py --nights 3`` (the default orbit propagated
    with the J2 propagator, fitted as TLEs a day apart, the last at the scenario epoch),
    then each night ``ovtraj launch-fit`` and ``ovtraj pipeline --target`` with a workspace
    of their own and no ``PREFECT_``/``OVTRAJ_`` variable but ``OVTRAJ_HOME``, in this
    process (tests/cli_runner.py: the entry point's body; the commands need no process of
    their own). Built once per test session: the xdist workers share it (a lock in the
    session's base folder); its users copy the store before changing it.

    Returns ``store``, ``plans`` (the plans' JSON files, oldest element set first),
    ``tles``, ``config`` and ``home`` (the workspace, with the three launch fits)."""
    import fcntl
    import json
    import subprocess
    import sys

    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # the folder every worker's base lies in
    folder = base / "replan-nights"
    folder.mkdir(exist_ok=True)
    done_file = folder / "done.json"
    with open(folder / "build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if done_file.is_file():
            return {k: _paths(v) for k, v in json.loads(done_file.read_text()).items()}
        from tests.cli_runner import run_cli

        config = replan_config(folder)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("PREFECT_", "OVTRAJ_"))}
        env["OVTRAJ_HOME"] = str(folder / "home")
        # The same environment in this process: the others of those variables unset.
        changes = {k: env.get(k) for k in os.environ.keys() | env.keys() if k.startswith(
            ("PREFECT_", "OVTRAJ_"))}  # fmt: skip

        def check(args: Any, done: subprocess.CompletedProcess) -> str:
            assert done.returncode == 0, f"{args}: exit {done.returncode}\n{done.stderr[-3000:]}"
            return done.stdout

        def run(*args: str) -> str:
            return check(args, subprocess.run(args, cwd=folder, env=env, capture_output=True,
                                              text=True, timeout=600))  # fmt: skip

        def ovtraj(*args: str) -> str:
            return check(args, run_cli(*args, env=changes, cwd=folder, timeout=600))

        tles = folder / "tles"
        first = str(1 - REPLAN_NIGHTS)
        example = str(REPO / "tools" / "example_tle.py")
        run(sys.executable, example, "--nights", str(REPLAN_NIGHTS), "--first-day", first,
            "--out", str(tles))  # fmt: skip
        store, plans = folder / "runs", []
        for tle in sorted(tles.glob("*.tle")):
            ovtraj("launch-fit", str(config), "--target", str(tle))
            # One verification round: a night's loop may stop unconverged (exit 1 without
            # the flag); the history records either.
            out = ovtraj("pipeline", str(config), "--target", str(tle), "--store", str(store),
                         "--json", "--allow-unconverged")  # fmt: skip
            plans.append(str(json.loads(out)["plan_json"]))
        found = {
            "store": str(store),
            "plans": plans,
            "tles": [str(t) for t in sorted(tles.glob("*.tle"))],
            "config": str(config),
            "home": str(folder / "home"),
        }
        done_file.write_text(json.dumps(found))
        return {k: _paths(v) for k, v in found.items()}


def _paths(value: Any) -> Any:
    return [Path(v) for v in value] if isinstance(value, list) else Path(value)
