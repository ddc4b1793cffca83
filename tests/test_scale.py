"""DoE and store at scale: batches sized by the run, the same results however
a run is batched, the trajectory selection per batch. The scale benchmark's scaled-down
run (a real Dask cluster, synthetic evaluations, the store commands on its run) is
tests/test_benchmarks.py's."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq

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
