"""DoE and store at scale (issue 48): batches sized by the run, the same results however
a run is batched, the trajectory selection per batch, and the scale benchmark's smoke run
(a real Dask cluster, synthetic evaluations, the store commands on its run)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.runs import RunStore, prepare_run, run_doe
from ovtraj.runs.execute import evaluate_batch, mission_context, trajectory_steps
from ovtraj.runs.schemas import stored_trajectory

ROOT = Path(__file__).resolve().parents[1]


def test_batches_grow_with_the_doe_and_past_max_batches(scenario):
    doe = scenario.mission.doe
    batching = doe.batching
    assert batching is not None
    # the pipeline's default DoE keeps the configured size
    assert doe.batch_size_for(24) == doe.batch_size
    # mid-size: each worker keeps batches_per_worker batches
    balanced = doe.batch_size_for(400)
    assert doe.batch_size < balanced < batching.preferred_batch_size
    assert -(-400 // balanced) >= batching.batches_per_worker * doe.workers
    # large: the preferred size, and no more than max_batches batches (task runs)
    assert doe.batch_size_for(10_000) == batching.preferred_batch_size
    for samples in (100_000, 1_000_000):
        assert -(-samples // doe.batch_size_for(samples)) <= min(batching.max_batches, 1000)
    unbatched = doe.model_copy(update={"batching": None})
    assert unbatched.batch_size_for(100_000) == doe.batch_size


def test_a_run_stores_the_same_results_however_it_is_batched(tmp_path, scenario):
    """12 samples in 3 batches of 4 (the shipped size) and in 2 of 6 (max_batches 2): the
    same run id and the same totals, stage rows and trajectory rows to the bit; the
    trajectories as the per-sample selection (stored_trajectory) keeps them; a run keeps
    the size it was stored with under other settings."""
    fit = find_launch_fit(scenario)
    doe = scenario.mission.doe
    doe = doe.model_copy(update={"batching": doe.batching.model_copy(update={"max_batches": 2})})
    coarse = scenario.model_copy(
        update={"mission": scenario.mission.model_copy(update={"doe": doe})}
    )
    runs = []
    for name, chosen in (("fine", scenario), ("coarse", coarse)):
        run = prepare_run(chosen, samples=12, seed=5, code="test", store=RunStore(tmp_path / name))
        run_doe(chosen, run, fit, batch_size=run.batch_size(chosen.mission.doe))
        runs.append(run)
    fine, coarse_run = runs
    assert fine.id == coarse_run.id
    assert len(fine.done_batches()) == 3 and len(coarse_run.done_batches()) == 2
    assert fine.batch_size(doe) == 4 and coarse_run.batch_size(scenario.mission.doe) == 6
    # a run stored before the size was recorded: its stored batches' size
    fine.update_manifest(batch_size=None)
    assert fine.batch_size(doe) == 4
    pd.testing.assert_frame_equal(fine.totals(), coarse_run.totals())
    for stage in ("rendezvous", "deorbit", "reentry"):
        pd.testing.assert_frame_equal(fine.stage(stage), coarse_run.stage(stage))
    sample = int(fine.samples()["sample_id"].iloc[5])
    for stage in ("rendezvous", "reentry"):
        pd.testing.assert_frame_equal(
            fine.trajectory(stage, sample), coarse_run.trajectory(stage, sample)
        )
    # the per-batch selection keeps the rows the per-sample selection keeps
    context = mission_context(scenario.resolved(), fit.to_dict())
    batch = fine.samples().iloc[5:6]
    (record,) = evaluate_batch(context, batch)
    steps = trajectory_steps(scenario)
    for stage in ("rendezvous", "reentry"):
        alone = stored_trajectory(record.trajectories[stage], stage, steps[stage])
        pd.testing.assert_frame_equal(alone, fine.trajectory(stage, sample), check_dtype=False)
    # every folder of the run stays small
    part = fine.directory / "totals"
    assert len(os.listdir(part)) == 3
    assert pq.read_metadata(coarse_run.directory / "totals" / "part-00000.parquet").num_rows == 6


def test_scale_benchmark_smoke_run(tmp_path):
    """The benchmark's every part but the window, scaled down: a real 2-worker Dask cluster
    with synthetic evaluations stores every sample, and runs/show/verify read its run."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("OVTRAJ_")}
    env["OVTRAJ_HOME"] = str(tmp_path / "home")
    result = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "scale.py"),
            "--samples",
            "24",
            "--fit-sizes",
            "16,24",
            "--baseline-size",
            "0",
            "--synthetic",
            "400",
            "--window-days",
            "0",
            "--json",
        ],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=580,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    figures = json.loads(result.stdout.strip().splitlines()[-1])
    pipeline = figures["pipeline"]
    assert pipeline["samples"] == 24 and set(pipeline["fits"]) == {"16", "24"}
    assert 0 < pipeline["store_bytes_per_sample"] < figures["goals"]["store_bytes_per_sample"]
    assert pipeline["evaluation_ms_per_sample"] > 0 and pipeline["front_points"] > 0
    assert np.isfinite(pipeline["fit_exponent"])
    orchestration = figures["orchestration"]
    assert orchestration["samples"] == orchestration["stored_samples"] == 400
    assert orchestration["largest_folder_entries"] <= orchestration["batches"] + 2
    assert figures["ratios"]["orchestration"] == pytest.approx(
        orchestration["wall_ms_per_sample"] / figures["goals"]["orchestration_ms_per_sample"]
    )
