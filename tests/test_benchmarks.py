"""Every script of ``benchmarks/`` run as the README runs it, on tiny settings.

The project's rule for benchmarks: measured side by side in one process, a readable table,
and as the last line one JSON object with the figures, the goals and the ratios; ``--json``
prints only that object. Every script runs here without ``--json`` (a table, then the
object as the last line); those marked ``twice`` run also with ``--json``, as a second
process at the same time, whose stdout must be that one line, the same object: the
cheapest, a few seconds each. The others (pipelines, a Prefect server, a Dask cluster,
heyoka builds) run once: their ``--json`` path is the same code as the others' (the table's
lines skipped, then the last ``print``). The figures are timings on tiny settings, so
nothing is asserted about their size; what is checked is what the scripts promise: the
documented keys, each ratio equal to its figure over its goal (recomputed here from the
printed figures), each verdict (``met``) the one its figures and goals give, and for the
scripts run twice the goals and the seeded results the same in both processes.

Tiny settings: the scripts' own options (fewer samples, seeds, repeats, generations,
plans); the launch search and the surrogate pipeline shortened through a scenario file
(``--config``), the launch as ``tests.conftest.shorten_launch_fit`` shortens the fit's
solves; the mission benchmarks use the shipped launch fit (``data/reference``). Every
file a script writes goes to the test's folder (``TMPDIR``, ``OVTRAJ_HOME``, Prefect's
home and task results).

The goals the scripts read from ``configs/benchmark_goals.yaml`` (``benchmarks/goals.py``):
every one of the shipped file read back, and a value that is not a finite positive number
refused in one line naming the file and the key.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import signal
import statistics
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from ovtraj.errors import ConfigError
from ovtraj.mission import reference
from tests.conftest import DEFAULT_SCENARIO, REPO, shorten_launch_search

# Left out of the fast tier (-m "not slow"): it runs every benchmark on its small setting.
pytestmark = pytest.mark.slow

BENCHMARKS = REPO / "benchmarks"
TIMEOUT_S = 600


def _scenario_data() -> dict[str, Any]:
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    # The file is written elsewhere: the launcher by its absolute path.
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    return data


def small_pipeline(folder: Path) -> Path:
    """The default scenario with a small surrogate pipeline (a 12-sample DoE, two
    regressors, one classifier, 3 folds, a short NSGA-II, one round of 2 infill points);
    the launch settings, hence the shipped launch fit, unchanged."""
    data = _scenario_data()
    mission = data["mission"]
    mission["doe"]["samples"] = 12
    mission["surrogate"].update(regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3)
    mission["optimize"].update(population=16, generations=10)
    mission["verify"].update(points_per_iteration=2, max_iterations=1, budget=2)
    path = folder / "small-pipeline.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def short_launch(folder: Path) -> Path:
    """The default scenario with the launch search of ``shorten_launch_fit`` (a small GA,
    coarser steps, short local phases)."""
    data = _scenario_data()
    shorten_launch_search(data["launch"])
    path = folder / "short-launch.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _close(ratio: float, value: float, digits: int = 3) -> bool:
    """``ratio`` is ``value`` as printed: rounded to ``digits``, from figures rounded too."""
    return math.isclose(ratio, value, rel_tol=2e-3, abs_tol=2 * 10.0**-digits)


# -- what each script promises --------------------------------------------------------------
def _check_timed(f: dict) -> None:
    """deorbit.py and reentry.py: one solve's median against its goal."""
    assert _close(f["ratio"], f["solve_s"] / f["goal_s"])
    assert f["met"] == (f["solve_s"] <= f["goal_s"])
    assert f["result"]["feasible"] is True


def _check_launch(f: dict) -> None:
    assert _close(f["time_ratio"], f["wall_s"] / f["goals"]["time_s_max"])
    assert f["published"], "the launcher publishes a figure at 200 km / 28.5 deg"
    for ref in f["published"]:
        assert _close(ref["ratio"], f["payload_kg"] / ref["payload_kg"], 4)
        assert ref["within"] == (abs(ref["ratio"] - 1.0) <= f["goals"]["payload_fraction_max"])
    assert f["met"]["payload"] == all(ref["within"] for ref in f["published"])
    assert [p["name"] for p in f["phases"]] == ["genetic", "slsqp", "trust-constr"]
    assert f["payload_kg"] in [p["payload_kg"] for p in f["phases"]]


def _check_propagation(f: dict) -> None:
    goals = f["goals"]
    assert _close(f["speedup_goal_ratio"], f["speedup"] / goals["speedup_min"])
    assert _close(f["speedup"], f["dop853_day_s"] / f["heyoka_day_s"], 2)
    # The equal-accuracy tolerance is the loosest whose error is within DOP853's.
    assert f["heyoka_error_m"] <= f["dop853_error_m"]
    assert [row["tol"] for row in f["tolerances"]] == [1e-10, 1e-12]
    assert set(f["rendezvous"]) == {"default scenario", "planes aligned at burn"}
    for case in f["rendezvous"].values():
        assert _close(case["goal_ratio"], case["solve_s"] / goals["rendezvous_s_max"])
        assert _close(case["dop853_day_fraction"], case["solve_s"] / f["dop853_day_s"])
    assert f["met"]["speedup"] == (f["speedup"] >= goals["speedup_min"])


def _check_maneuver(f: dict) -> None:
    bests = []
    for row in f["methods"].values():
        assert row["runs"] == f["seeds"]
        assert row["success_rate"] == pytest.approx(row["successes"] / row["runs"], abs=1e-3)
        if row["best_tof_s"] is not None:
            bests.append(row["best_tof_s"])
            assert row["best_tof_s"] <= row["median_tof_s"] <= row["worst_tof_s"]
    # The best known time of flight is the best of every method's runs.
    assert f["best_tof_s"] == min(bests)


def _check_catalog(f: dict) -> None:
    goals, ratios = f["goals"], f["ratios"]
    for name in ("query_plans", "query_runs"):
        assert _close(ratios[name], f[f"{name}_s"] / goals["query_s_max"], 4)
    for name in ("runs_command", "runs_where_command"):
        assert _close(ratios[name], f[f"{name}_s"] / goals["runs_command_s_max"])
    query_s = max(f["query_plans_s"], f["query_runs_s"])
    assert f["met"]["query"] == (query_s <= goals["query_s_max"])
    command_s = max(f["runs_command_s"], f["runs_where_command_s"])
    assert f["met"]["runs_command"] == (command_s <= goals["runs_command_s_max"])
    for key, value in f.items():
        if key.endswith("_s") or key.endswith("_s_per_run"):
            assert math.isfinite(value) and value > 0, key
    # The synthetic store: families of runs, each with one pipeline result and one plan,
    # every one catalogued without an error.
    kinds = f["rows_by_kind"]
    assert kinds["run"] == f["runs"] and f["runs"] % f["families"] == 0
    assert kinds["pipeline"] == kinds["plan"] == f["families"]
    assert f["rows"] == sum(kinds.values()) and f["row_errors"] == 0
    assert f["catalog_bytes"] > 0
    assert _close(f["catalog_bytes_per_row"], f["catalog_bytes"] / f["rows"], 1)
    assert 0 <= f["query_plans_rows"] <= kinds["plan"]
    assert 0 < f["query_runs_rows"] <= kinds["run"]  # the newest month of one target's runs
    assert f["runs_command_lines"] > 0 and f["runs_where_command_lines"] > 0


def _check_deorbit_burn(f: dict) -> None:
    assert f["met"] == all(row["matches"] is not False for row in f["published"])
    assert f["monte_carlo"]["runs"] == 1 and f["monte_carlo"]["workers"] == 1
    assert f["burn_angles"] == 11  # the case's study angles (configs/cases/shuttle_deorbit.yaml)


def _check_doe(f: dict) -> None:
    assert _close(f["speedup_ratio"], f["speedup_2_workers"] / f["speedup_goal"])
    assert _close(f["overhead_ratio"], f["overhead"] / f["overhead_goal"])
    # The walls are printed to 10 ms: their ratio within ~1 % of the speed-up.
    walls = f["wall_1_worker_s"] / f["wall_2_workers_s"]
    assert f["speedup_2_workers"] == pytest.approx(walls, rel=0.03)
    assert f["samples"] == 2 and f["repeats"] == 1


def _check_high_fidelity(f: dict) -> None:
    goals, ratios, rows = f["goals"], f["ratios"], f["breakdown"]
    assert set(rows) == {"gravity", "all", "j2"}  # --breakdown gravity,all,j2
    for name, row in rows.items():
        assert _close(row["speedup"], row["dop853_ms"] / row["heyoka_ms"])
        # DOP853's rtol: the loosest as accurate as heyoka's tolerance, else the tightest.
        tried = row["dop853_rtols"]
        as_accurate = [r["rtol"] for r in tried if r["error_m"] <= row["heyoka_error_m"]]
        assert row["equal_accuracy"] == bool(as_accurate)
        loosest = max(as_accurate) if as_accurate else min(r["rtol"] for r in tried)
        assert row["dop853_rtol"] == loosest
        assert row["dop853_error_m"] == next(r for r in tried if r["rtol"] == loosest)["error_m"]
        if name == "all":  # a term's cost: its row's time less gravity's
            assert _close(row["term_ms"], row["heyoka_ms"] - rows["gravity"]["heyoka_ms"])
    assert f["speedup_vs_dop853"] == rows["all"]["speedup"]
    assert f["day_all_terms_ms"] == rows["all"]["heyoka_ms"]
    speedup_goal = goals["speedup_vs_dop853_min"]
    assert _close(ratios["speedup_vs_dop853"], f["speedup_vs_dop853"] / speedup_goal, 4)
    assert f["met"]["speedup_vs_dop853"] == (f["speedup_vs_dop853"] >= speedup_goal)
    degrees = {row["degree"]: row["difference_m"] for row in f["degrees"]["rows"]}
    assert set(degrees) == {20, f["degrees"]["reference_degree"]} == {20, 70}  # --degrees 20
    assert set(degrees[70].values()) == {0.0}
    assert f["degree_20_vs_70_m"] == max(degrees[20].values())
    degree_goal = goals["degree_20_vs_70_m_max"]
    assert _close(ratios["degree_20_vs_70_m"], f["degree_20_vs_70_m"] / degree_goal)
    assert f["met"]["degree_20_vs_70_m"] == (f["degree_20_vs_70_m"] <= degree_goal)
    fields = [row["field"] for row in f["thresholds"]]
    assert fields == ["elp_threshold"]  # --thresholds elp
    assert all(row["shipped"] > row["default"] for row in f["thresholds"])
    assert "cold_compile_s" not in f["compile"]  # --no-cold-compile
    assert f["compile"]["first_build_s"] > 0


def _check_interior_point(f: dict) -> None:
    ours, theirs = f["solvers"]["interior point"], f["solvers"]["trust-constr"]
    assert _close(f["speedup"], theirs["total_ms"] / ours["total_ms"])
    assert ours["converged"] <= f["problems"] and theirs["converged"] <= f["problems"]


def _check_mission(f: dict) -> None:
    assert _close(f["ratio"], f["median_eval_s"] / f["dop853_day_s"])
    assert _close(f["goal_ratio"], f["ratio"] / f["ratio_goal"])
    for stage, seconds in f["stages"].items():
        assert _close(f["stage_ratios"][stage], seconds / f["dop853_day_s"])
    settings = reference.load_settings()  # configs/mission_reference.yaml: its designs
    assert f["designs"] == settings.designs + len(settings.extra_designs)


def _check_monte_carlo(f: dict) -> None:
    p95 = (f["closed_loop"]["landing_miss_m"] or {}).get("p95")
    assert f["met"] == (p95 is not None and p95 <= f["goal"]["p95_landing_miss_m_max"])
    assert f["runs"] == 1


def _check_optimal_entry(f: dict) -> None:
    assert set(f["cases"]) == {
        "suborbital_return",
        "shuttle_crossrange",
        "shuttle_crossrange_heating",
    }
    for case in f["cases"].values():
        assert _close(case["time_ratio"], case["ours_s"] / case["peer_s"])
        gap = abs(case["ours_objective"] / case["peer_objective"] - 1.0)
        assert case["objective_gap"] == pytest.approx(gap, abs=1e-6)
    no_slower = all(c["time_ratio"] <= f["goals"]["time_ratio_max"] for c in f["cases"].values())
    assert f["met"]["no_slower"] == no_slower


def _check_plan_vs_front(f: dict) -> None:
    aimed = f["chains"]["aimed"]
    assert aimed["front_points"] == 1  # --plans 1
    assert aimed["plan_errors"] == 0
    met = (
        aimed["max_dv_total_mps"] <= f["goals"]["plan_dv_total_mps_max"]
        and aimed["max_t_total_s"] <= f["goals"]["plan_t_total_s_max"]
        and aimed["max_m_load_kg"] <= f["goals"]["plan_m_load_kg_max"]
    )
    assert f["met"]["plans"] == met
    assert aimed["design_space"]["designs"] == 2


def _check_reproducibility(f: dict) -> None:
    rows = f["variants"]
    assert [(r["openblas_coretype"], r["openblas_threads"]) for r in rows] == [
        ("Haswell", 1),
        ("Sandybridge", 2),
    ]
    assert f["pinned"] and f["goals"]["byte_identical"] == "all"
    identical = sum(r["files_identical"] == r["files"] == rows[0]["files"] for r in rows)
    assert f["figures"]["identical_variants"] == identical
    assert _close(f["ratios"]["identical_variants"], identical / len(rows))
    assert f["met"] == (identical == len(rows))
    assert f["met"], rows  # the pin holds: the same bytes under both kernels
    assert f["figures"]["pipeline_ids"] == 1 and len(f["figures"]["picked_samples"]) == 1


def _check_store(f: dict) -> None:
    goal = f["goal_bytes_per_sample"]
    assert _close(f["ratio_bytes_to_goal"], f["bytes_per_sample"] / goal)
    assert _close(f["ratio_format_2_to_1"], f["bytes_per_sample"] / f["bytes_per_sample_format_1"])
    assert f["goal_met"] == (f["bytes_per_sample"] <= goal)


def _check_convergence(f: dict) -> None:
    runs, goals = f["runs"], f["goals"]
    assert [r["seed"] for r in runs] == [2026] and f["seeds"] == 1
    assert f["converged"] == sum(r["converged"] for r in runs)
    assert _close(f["worst_ratio"], min(r["reference_ratio"] for r in runs), 6)
    for r in runs:  # each run's ratio is its hypervolume over the stored reference's
        assert _close(r["reference_ratio"], r["hypervolume"] / f["reference_hypervolume"], 6)
    assert f["median_evaluations"] == statistics.median(r["evaluations"] for r in runs)
    assert f["met"]["converged"] == (f["converged"] >= goals["converged_min"])
    assert f["met"]["median_evaluations"] == (
        f["median_evaluations"] <= goals["median_evaluations_max"]
    )
    probe = f["cliff_probe"]
    assert probe["designs"] == 2 and 0 <= probe["feasible_pairs"] <= 6
    large = probe["large_changes"]
    if probe["feasible_pairs"]:
        assert _close(f["smooth_share"], 1 - len(large) / probe["feasible_pairs"], 6)
    assert f["large_without_pass_change"] == sum(c["t_change_h"] < 12.0 for c in large)


def _check_surrogate_vs_direct(f: dict) -> None:
    direct = f["direct"]
    assert [s["seed"] for s in f["seeds"]] == [2026]
    ratio = min(s["hypervolume"] for s in f["seeds"]) / direct["hypervolume"]
    assert _close(f["hypervolume_ratio"], ratio, 4)
    evaluations = max(s["evaluations"] for s in f["seeds"]) / direct["evaluations"]
    assert _close(f["evaluation_ratio"], evaluations, 4)
    goals = f["goals"]
    assert f["met"]["hypervolume"] == (f["hypervolume_ratio"] >= goals["hypervolume_ratio_min"])
    assert f["met"]["evaluations"] == (f["evaluation_ratio"] <= goals["evaluation_ratio_max"])


def _check_scale(f: dict) -> None:
    """The scaled-down run: every part's figures, the ratios their goals' (the window is
    tests/test_window.py's)."""
    pipeline, orchestration, goals = f["pipeline"], f["orchestration"], f["goals"]
    assert pipeline["samples"] == 24 and set(pipeline["fits"]) == {"16", "24"}
    assert 0 < pipeline["store_bytes_per_sample"] < goals["store_bytes_per_sample"]
    assert pipeline["evaluation_ms_per_sample"] > 0 and pipeline["front_points"] > 0
    assert math.isfinite(pipeline["fit_exponent"])
    assert _close(f["ratios"]["pipeline"], pipeline["pipeline_s"] / goals["pipeline_s"])
    # a real 2-worker Dask cluster stored every synthetic sample; runs/show/verify read it
    assert orchestration["samples"] == orchestration["stored_samples"] == 400
    assert orchestration["largest_folder_entries"] <= orchestration["batches"] + 2
    assert min(orchestration[k] for k in ("runs_s", "show_s", "verify_s")) > 0
    assert _close(
        f["ratios"]["orchestration"],
        orchestration["wall_ms_per_sample"] / goals["orchestration_ms_per_sample"],
    )
    assert f["met"]["orchestration"] == (f["ratios"]["orchestration"] <= 1.0)


@dataclass(frozen=True)
class Benchmark:
    name: str
    args: Callable[[Path], list[str]]  # tiny settings (files written in the given folder)
    keys: frozenset[str]  # documented top-level keys of the JSON object
    check: Callable[[dict], None]
    same: tuple[str, ...]  # keys equal in both processes: goals and seeded results
    # Run with --json too (a second process, at the same time). Only the cheapest scripts
    # (a few seconds) do: the others' table and its last line are checked, --json's
    # one-line path (the table's lines skipped, then the last ``print``) being the same
    # code in every script.
    twice: bool = False


BENCHMARK_CASES = (
    Benchmark(
        "catalog",
        lambda _: ["--runs", "50", "--repeats", "1"],
        frozenset(
            {
                "runs",
                "rows",
                "rows_by_kind",
                "catalog_bytes",
                "catalog_bytes_per_row",
                "rebuild_s",
                "refresh_unchanged_s",
                "read_s",
                "query_plans_s",
                "query_runs_s",
                "runs_command_s",
                "runs_where_command_s",
                "goals",
                "ratios",
                "met",
            }
        ),
        _check_catalog,
        ("goals", "runs", "families", "rows", "rows_by_kind", "where", "query_plans_rows"),
    ),
    Benchmark(
        "deorbit",
        lambda _: [],
        frozenset({"solve_s", "goal_s", "ratio", "met", "result", "forecast_s", "scan_s"}),
        _check_timed,
        ("goal_s", "result", "propagations", "iterations", "forecast_crossings"),
        twice=True,
    ),
    Benchmark(
        "deorbit_burn",
        lambda _: ["1", "1", "--repeats", "1"],
        frozenset({"solve_s", "iterations", "dv_mps", "monte_carlo", "published", "met"}),
        _check_deorbit_burn,
        ("iterations", "dv_mps", "zero_speed_error_angles_deg"),
    ),
    Benchmark(
        "doe",
        lambda _: ["--samples", "2", "--batch", "2", "--repeats", "1", "--serial-samples", "0"],
        frozenset(
            {
                "speedup_2_workers",
                "speedup_goal",
                "speedup_ratio",
                "overhead",
                "overhead_goal",
                "overhead_ratio",
            }
        ),
        _check_doe,
        ("speedup_goal", "overhead_goal", "samples", "batch_size"),
    ),
    Benchmark(
        "high_fidelity",
        lambda _: [
            *("--hours", "1", "--repeats", "1", "--degrees", "20"),
            *("--breakdown", "gravity,all,j2", "--thresholds", "elp", "--no-cold-compile"),
        ],
        frozenset(
            {
                "breakdown",
                "numpy_rhs",
                "speedup_vs_dop853",
                "day_all_terms_ms",
                "degrees",
                "degree_20_vs_70_m",
                "thresholds",
                "compile",
                "goals",
                "ratios",
                "met",
            }
        ),
        _check_high_fidelity,
        # Seeded results: the same compiled code flies the same arcs in both processes.
        ("goals", "hours", "origin", "degree_20_vs_70_m"),
    ),
    Benchmark(
        "interior_point",
        lambda _: ["--repeats", "1"],
        frozenset(
            {
                "problems",
                "solvers",
                "speedup",
                "max_dv_difference_mps",
                "max_dv_difference_goal_mps",
                "max_arrival_difference_s",
                "max_arrival_difference_goal_s",
            }
        ),
        _check_interior_point,
        ("problems", "max_dv_difference_goal_mps", "max_arrival_difference_goal_s"),
    ),
    Benchmark(
        "launch",
        lambda folder: ["--config", str(short_launch(folder))],
        frozenset({"payload_kg", "wall_s", "published", "goals", "time_ratio", "met"}),
        _check_launch,
        ("goals", "altitude_km", "inclination_deg"),
    ),
    Benchmark(
        "maneuver",
        lambda _: ["--seeds", "1", "--generations", "5"],
        frozenset({"methods", "best_tof_s", "success_tolerance_s", "generations", "seeds"}),
        _check_maneuver,
        ("best_tof_s", "success_tolerance_s", "population"),
    ),
    Benchmark(
        "mission",
        lambda _: ["--warm-up", "1", "--repeats", "1", "--dop853-repeats", "1"],
        frozenset({"median_eval_s", "dop853_day_s", "ratio", "ratio_goal", "goal_ratio", "stages"}),
        _check_mission,
        ("ratio_goal", "designs", "feasible_designs", "stage_counts"),
    ),
    Benchmark(
        "monte_carlo",
        lambda _: ["--runs", "1"],
        frozenset({"seconds_per_run", "closed_loop", "open_loop", "goal", "met"}),
        _check_monte_carlo,
        ("goal", "runs", "seed"),
    ),
    Benchmark(
        "optimal_entry",
        lambda _: ["--repeats", "1"],
        frozenset({"cases", "goals", "met"}),
        _check_optimal_entry,
        ("goals",),
    ),
    Benchmark(
        "plan_vs_front",
        lambda folder: [
            *("--seeds", "2026", "--designs", "2", "--chains", "aimed", "--plans", "1"),
            *("--config", str(small_pipeline(folder))),
        ],
        frozenset({"chains", "goals", "met"}),
        _check_plan_vs_front,
        ("goals",),
    ),
    Benchmark(
        "propagation",
        lambda _: ["--repeats", "1"],
        frozenset({"tolerances", "speedup", "goals", "speedup_goal_ratio", "rendezvous", "met"}),
        _check_propagation,
        ("goals", "heyoka_equal_accuracy_tol"),
    ),
    Benchmark(
        "reentry",
        lambda _: [],
        frozenset({"solve_s", "goal_s", "ratio", "met", "result", "trajectories"}),
        _check_timed,
        ("goal_s", "result", "trajectories"),
        twice=True,
    ),
    Benchmark(
        "reproducibility",
        lambda folder: [
            *("--config", str(small_pipeline(folder)), "--samples", "16"),
            *("--variants", "Haswell:1,Sandybridge:2"),
        ],
        frozenset({"variants", "figures", "goals", "ratios", "met"}),
        _check_reproducibility,
        ("goals",),
    ),
    Benchmark(
        "store",
        lambda _: ["--samples", "2"],
        frozenset(
            {
                "bytes_per_sample",
                "goal_bytes_per_sample",
                "ratio_bytes_to_goal",
                "ratio_format_2_to_1",
                "goal_met",
            }
        ),
        _check_store,
        ("goal_bytes_per_sample", "samples", "verified_files"),
        twice=True,
    ),
    Benchmark(
        "scale",
        lambda _: [
            *("--samples", "24", "--fit-sizes", "16,24", "--baseline-size", "0"),
            *("--synthetic", "400", "--window-days", "0"),
        ],
        frozenset({"pipeline", "orchestration", "goals", "ratios", "met"}),
        _check_scale,
        ("goals",),
    ),
    Benchmark(
        "convergence",
        lambda folder: [
            *("--seeds", "2026", "--workers", "1", "--cliff-designs", "2"),
            *("--config", str(small_pipeline(folder))),
        ],
        frozenset({"converged", "worst_ratio", "median_evaluations", "cliff_probe", "goals"}),
        _check_convergence,
        ("goals",),
    ),
    Benchmark(
        "surrogate_vs_direct",
        lambda folder: [
            *("--seeds", "2026", "--doe-samples", "12", "--population", "8"),
            *("--generations", "2", "--workers", "1", "--config", str(small_pipeline(folder))),
        ],
        frozenset(
            {"hypervolume_ratio", "evaluation_ratio", "wall_ratio", "direct", "seeds", "goals"}
        ),
        _check_surrogate_vs_direct,
        ("goals",),
    ),
)


def test_every_benchmark_script_is_tested():
    scripts = {path.stem for path in BENCHMARKS.glob("*.py")} - {"goals"}  # the goals' loader
    assert scripts == {case.name for case in BENCHMARK_CASES}


def _goals_loader() -> Any:
    """A fresh ``benchmarks/goals.py`` (its own cache of the file)."""
    spec = importlib.util.spec_from_file_location("benchmark_goals", BENCHMARKS / "goals.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_goal_of_the_shipped_file_is_read():
    loader = _goals_loader()
    data = yaml.safe_load(loader.FILE.read_text(encoding="utf-8"))
    for script, section in data.items():
        assert (BENCHMARKS / f"{script}.py").is_file(), script
        assert loader.goals(script) == section
        assert all(loader.goal(script, name) == value for name, value in section.items())


@pytest.mark.parametrize("value", ["0", "-1.0", ".nan", ".inf", "true", "'1'", "[1]", "4.0e9"])
def test_a_goal_not_a_finite_positive_number_is_one_line_naming_the_file_and_key(value, tmp_path):
    loader = _goals_loader()
    loader.FILE = tmp_path / "benchmark_goals.yaml"
    loader.FILE.write_text(f"scale:\n  fit_s: 60.0\n  pipeline_s: {value}\n", encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        loader.goal("scale", "fit_s")
    message = str(err.value)
    assert "\n" not in message and str(loader.FILE) in message and "scale.pipeline_s" in message


def _environment(folder: Path) -> dict[str, str]:
    """Every file the script writes under ``folder``; no network for Prefect."""
    folder.mkdir(parents=True)
    (folder / "tmp").mkdir()
    return dict(
        os.environ,
        TMPDIR=str(folder / "tmp"),
        OVTRAJ_HOME=str(folder / "home"),
        OVTRAJ_PREFECT_RESULTS=str(folder / "task-results"),
        PREFECT_HOME=str(folder / "prefect-home"),
        PREFECT_SERVER_ANALYTICS_ENABLED="false",
    )


def _run_both(script: Path, args: list[str], folder: Path, twice: bool) -> dict[str, str]:
    """stdout of ``script args --json`` (when ``twice``) and of ``script args``, run at the
    same time (their output to files: a full pipe would hold one process while the other
    is read)."""
    processes = {}
    for mode in ("json", "table") if twice else ("table",):
        env = _environment(folder / mode)
        with (
            open(folder / mode / "stdout", "wb") as stdout,
            open(folder / mode / "stderr", "wb") as stderr,
        ):
            command = [sys.executable, str(script), *args]
            processes[mode] = subprocess.Popen(
                command + (["--json"] if mode == "json" else []),
                cwd=REPO,
                env=env,
                stdout=stdout,
                stderr=stderr,
                start_new_session=True,  # on a timeout, its Prefect server is stopped with it
            )
    out = {}
    try:
        for mode, process in processes.items():
            process.wait(timeout=TIMEOUT_S)
            stderr = (folder / mode / "stderr").read_text(encoding="utf-8", errors="replace")
            assert process.returncode == 0, f"{script.name} ({mode}) failed:\n{stderr[-4000:]}"
            out[mode] = (folder / mode / "stdout").read_text(encoding="utf-8")
    finally:
        for process in processes.values():
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
    return out


@pytest.mark.parametrize("case", BENCHMARK_CASES, ids=lambda case: case.name)
def test_benchmark_prints_a_table_then_its_figures_as_one_json_line(case, tmp_path):
    out = _run_both(BENCHMARKS / f"{case.name}.py", case.args(tmp_path), tmp_path, case.twice)

    # Without --json: a table, then the object as the last line (strict JSON: no NaN).
    lines = [line for line in out["table"].splitlines() if line.strip()]
    last = json.loads(lines[-1], parse_constant=pytest.fail)
    assert isinstance(last, dict)
    assert case.keys <= set(last), case.keys - set(last)
    case.check(last)
    only = last
    if case.twice:  # --json: exactly one line, the same object
        json_lines = out["json"].splitlines()
        assert len(json_lines) == 1, out["json"][-2000:]
        only = json.loads(json_lines[0], parse_constant=pytest.fail)
        assert set(last) == set(only)
        case.check(only)
    table = lines[:-1]
    assert len(table) >= 2, out["table"]
    assert not any(line.lstrip().startswith("{") for line in table), "one JSON line, the last"
    assert any(any(ch.isdigit() for ch in line) for line in table), "a table with figures"
    for key in case.same:
        assert last[key] == only[key], key
