"""Running a DoE into the store (serial library path; the Prefect flow parallelises it)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pandas as pd

from ovtraj.config import Scenario
from ovtraj.launch.fit import LaunchFit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, MissionRecord, evaluate
from ovtraj.runs.doe import latin_hypercube
from ovtraj.runs.store import Run, RunStore, StoreError

# Counts mission evaluations in this process (tests assert that a re-run makes none).
EVALUATIONS = {"count": 0}


def split_batches(samples: pd.DataFrame, batch_size: int) -> list[pd.DataFrame]:
    if batch_size < 1:
        raise ValueError(f"batch_size must be >= 1, got {batch_size}")
    return [samples.iloc[i : i + batch_size] for i in range(0, len(samples), batch_size)]


def evaluate_batch(context: MissionContext, batch: pd.DataFrame) -> list[MissionRecord]:
    """Every sample of a batch; a failing sample is recorded, never raised."""
    records = []
    for row in batch.itertuples(index=False):
        EVALUATIONS["count"] += 1
        design = MissionDesign(**{name: float(getattr(row, name)) for name in DESIGN_NAMES})
        records.append(evaluate(context, design))
    return records


def prepare_run(
    scenario: Scenario,
    *,
    samples: int,
    seed: int,
    code: str,
    store: RunStore,
    parent: Run | None = None,
) -> Run:
    """The run of a scenario's DoE; with ``parent``, its samples plus ``samples`` more.

    A child run adopts the parent's stored batches (:meth:`Run.adopt`). Without
    ``parent``, a stored Latin-hypercube run of the same scenario, seed and code with
    fewer samples is extended by a further hypercube rather than a second, unrelated
    one drawn (:meth:`RunStore.latin_hypercube_run`): DoEs of different sizes share
    their samples (the nightly DoE and the re-plan), and a run of the same size is
    reopened.
    """
    if scenario.mission is None:
        raise ValueError("the scenario has no mission section")
    bounds = scenario.mission.design_bounds
    if parent is None:
        resolved = scenario.resolved()
        base = store.latin_hypercube_run(resolved, seed, code, at_most=samples)
        if base is None:
            samples_table = latin_hypercube(bounds, samples, seed)
            return store.create(resolved=resolved, samples=samples_table, seed=seed, code=code)
        have = int(base.manifest["samples"])
        if have == samples:
            return base
        parent, samples = base, samples - have
    previous = parent.samples()
    more = latin_hypercube(bounds, samples, seed, first_id=int(previous["sample_id"].max()) + 1)
    return extend_run(scenario, parent, more, seed=seed, code=code, store=store)


def extend_run(
    scenario: Scenario,
    parent: Run,
    designs: pd.DataFrame,
    *,
    seed: int,
    code: str,
    store: RunStore,
    origin: str = "latin hypercube",
) -> Run:
    """A child run of ``parent``: its samples plus ``designs`` (new ids), parent batches adopted.

    ``designs`` holds the design variables, with or without ``sample_id`` (numbered on
    from the parent's when absent). ``origin`` says where the new samples come from
    (the Latin hypercube, or the pipeline's infill).
    """
    previous = parent.samples()
    more = designs.reset_index(drop=True)
    if "sample_id" not in more:
        first = int(previous["sample_id"].max()) + 1 if len(previous) else 0
        more = more.assign(sample_id=np.arange(first, first + len(more), dtype=np.int64))
    more = more[["sample_id", *DESIGN_NAMES]]
    child = store.create(
        resolved=scenario.resolved(),
        samples=pd.concat([previous, more], ignore_index=True),
        seed=seed,
        code=code,
        parent=parent.id,
        origin=origin,
    )
    child.adopt(parent)
    return child


def trajectory_steps(scenario: Scenario) -> dict[str, float]:
    """The stored sampling of each stage's trajectory (``mission.store``) [s]."""
    store = scenario.mission.store
    orbit = store.orbit_trajectory_step_s
    return {
        "rendezvous": orbit,
        "transfer": orbit,
        "deorbit": orbit,
        "reentry": store.entry_trajectory_step_s,
    }


def store_batch(
    run: Run,
    scenario: Scenario,
    context: MissionContext,
    batch_index: int,
    batch: pd.DataFrame,
    *,
    wait_s: float = 0.0,
) -> bool | None:
    """Evaluate and store one batch under its claim.

    Returns True when this process stored it, False when it was already stored
    (possibly by another process meanwhile), None when another process holds its
    claim and ``wait_s`` is 0.
    """
    with run.claim(batch_index, wait_s=wait_s) as claimed:
        if not claimed:
            return None
        if run.is_stored(batch_index):
            return False
        records = evaluate_batch(context, batch)
        ids = [int(i) for i in batch["sample_id"]]
        return run.write_batch(
            batch_index, records, ids, trajectory_steps=trajectory_steps(scenario)
        )


def run_doe(
    scenario: Scenario,
    run: Run,
    launch_fit: LaunchFit,
    *,
    batch_size: int,
    progress: Callable[[str], None] | None = None,
) -> Run:
    """Evaluate every batch the run does not hold yet, serially, and finish the manifest.

    Batches that another process is computing are left to it at first, then waited
    for (``mission.doe.claim_wait_s``); one whose process died is computed here. A
    complete run is not written to at all.
    """
    say = progress or (lambda _: None)
    batches = run.batches(batch_size)
    if not [k for k, _ in batches if not run.is_stored(k)]:
        return finish(run)
    context = MissionContext(scenario, launch_fit)

    def evaluate(k: int, batch: pd.DataFrame, wait_s: float) -> bool:
        start = time.perf_counter()
        stored = store_batch(run, scenario, context, k, batch, wait_s=wait_s)
        if stored:
            say(
                f"batch {k + 1}/{len(batches)}: {len(batch)} samples in "
                f"{time.perf_counter() - start:.1f} s"
            )
        return stored is not None

    with run.working() as removed:
        if removed:
            say(f"removed {len(removed)} temporary file(s) of an interrupted write")
        run.update_manifest(batches=len(batches))
        waiting = [(k, b) for k, b in batches if not run.is_stored(k) and not evaluate(k, b, 0.0)]
        for k, batch in waiting:
            say(f"batch {k + 1}/{len(batches)}: another process is computing it; waiting")
            evaluate(k, batch, scenario.mission.doe.claim_wait_s)
    return finish(run)


def finish(run: Run) -> Run:
    """Set the manifest's status and counts from the stored batches (written only if changed).

    ``complete`` when every sample is stored; otherwise ``running`` while another
    process works on the run, else ``incomplete``.
    """
    totals = run.totals()
    samples = len(run.samples())
    if len(totals) == samples:
        status = "complete"
    elif run.in_use():
        status = "running"
    else:
        status = "incomplete"
    run.update_manifest(
        status=status,
        evaluated=len(totals),
        feasible=int(totals["feasible"].sum()) if len(totals) else 0,
    )
    return run


def replay(run: Run) -> pd.DataFrame:
    """The mission totals re-derived from the stored stage rows (no simulation).

    ``dV_total`` = rendezvous + transfer impulses + the deorbit impulse, ``M_load`` the
    launch payload, ``T_total`` from the drop to the terminal interface (the deorbit
    starts at the end of the transfer, its times count from there).
    """
    if not run.done_batches():
        raise StoreError(f"run {run.id} has no stored batch: nothing to replay")
    samples = run.samples()[["sample_id"]]
    frames = {
        stage: run.stage(stage)
        for stage in ("launch", "rendezvous", "transfer", "deorbit", "reentry")
    }
    out = samples.copy()
    merged = samples
    for stage, frame in frames.items():
        if len(frame) == 0:
            return out.assign(
                feasible=False, t_total_s=np.nan, dv_total_mps=np.nan, m_load_kg=np.nan
            )
        merged = merged.merge(
            frame.add_prefix(f"{stage}.").rename(columns={f"{stage}.sample_id": "sample_id"}),
            on="sample_id",
            how="left",
        )
    feasible = np.ones(len(merged), dtype=bool)
    for stage in frames:
        feasible &= merged[f"{stage}.feasible"].fillna(False).astype(bool).to_numpy()
    dv = (
        merged["rendezvous.dv_total_mps"]
        + merged["transfer.dv_total_mps"]
        + merged["deorbit.dv_mps"]
    )
    t_terminal = (
        merged["transfer.burn2_t_s"]
        + merged["deorbit.entry_time_s"]
        + merged["reentry.flight_time_s"]
    )
    out["feasible"] = feasible
    out["t_total_s"] = np.where(feasible, t_terminal - merged["launch.drop_time_s"], np.nan)
    out["dv_total_mps"] = np.where(feasible, dv, np.nan)
    out["m_load_kg"] = np.where(feasible, merged["launch.payload_kg"], np.nan)
    return out
