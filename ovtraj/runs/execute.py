"""Running a DoE into the store: the library path of ``ovtraj run`` (every runner), and the
batch job the Prefect DoE task wraps."""

from __future__ import annotations

import concurrent.futures
import hashlib
import json
import logging
import shutil
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.config.io_limits import io_limits
from ovtraj.config.orchestration import DaskSettings, load_orchestration
from ovtraj.environment import require_pinned_kernel
from ovtraj.formatting import byte_size, printable
from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, MissionRecord, evaluate
from ovtraj.mission.design_space import latin_hypercube
from ovtraj.parallel import EVALUATION_BLAS_THREADS, Bounded, blas_threads
from ovtraj.runs.runners import BatchPool, ClusterError, RunnerChoice, StartedPool, batch_pool
from ovtraj.runs.store import Run, RunStore, StoreError
from ovtraj.store.backends import S3Path

logger = logging.getLogger(__name__)

# Counts mission evaluations in this process (tests assert that a re-run makes none).
EVALUATIONS = {"count": 0}


def evaluate_batch(context: MissionContext, batch: pd.DataFrame) -> list[MissionRecord]:
    """Every sample of a batch; a failing sample is recorded, never raised.

    Every runner's batches come here, in whatever process runs them: one that runs another
    OpenBLAS kernel than the pin is refused (:class:`~ovtraj.environment.BlasKernelError`),
    since it would store other last bits under the same run id (:mod:`ovtraj.environment`).
    """
    require_pinned_kernel()
    records = []
    with blas_threads(EVALUATION_BLAS_THREADS):
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
    if int(samples) < 1 or int(seed) < 0:
        raise ValueError(f"samples must be >= 1 and seed >= 0; got samples {samples}, seed {seed}")
    bounds = scenario.mission.design_bounds
    if parent is None:
        resolved = scenario.resolved()
        base = store.latin_hypercube_run(resolved, seed, code, at_most=samples)
        if base is None:
            check_free_disk(store, samples)
            samples_table = latin_hypercube(bounds, samples, seed)
            return store.create(resolved=resolved, samples=samples_table, seed=seed, code=code)
        have = int(base.manifest["samples"])
        if have == samples:
            return base
        parent, samples = base, samples - have
    check_free_disk(store, samples)  # the parent's batches are adopted as hard links
    previous = parent.samples()
    more = latin_hypercube(bounds, samples, seed, first_id=int(previous["sample_id"].max()) + 1)
    return extend_run(scenario, parent, more, seed=seed, code=code, store=store)


def doe_size_estimate(samples: int) -> float:
    """Bytes [B] ``samples`` new DoE samples take in the run store: the measured
    ``doe_bytes_per_sample`` of ``configs/io_limits.yaml`` times their number."""
    return samples * io_limits().doe_bytes_per_sample


def check_free_disk(store: RunStore, samples: int) -> None:
    """Refuse a DoE of ``samples`` new samples whose estimated size is above the free
    disk of the store's folder (:class:`StoreError` naming both), before it writes a
    byte; say the estimate of a large one (above ``doe_estimate_shown_gib``). An object
    store (``s3://``) reports no free space: its DoE is only announced."""
    estimate = doe_size_estimate(samples)
    limits = io_limits()
    where = store.root
    if not isinstance(where, S3Path):
        folder = Path(where)
        while not folder.exists() and folder != folder.parent:  # the store made on first write
            folder = folder.parent
        free = shutil.disk_usage(folder).free
        if estimate > free:
            raise StoreError(
                f"{printable(str(where))}: a DoE of {samples} samples takes "
                f"~{byte_size(round(estimate))} "
                f"({byte_size(round(limits.doe_bytes_per_sample))} a sample, "
                f"configs/io_limits.yaml), more than the {byte_size(free)} free on its disk"
            )
    if estimate > limits.doe_estimate_shown_bytes:
        logger.info(
            "a DoE of %d samples: ~%s in %s (%s a sample, measured)",
            samples,
            byte_size(round(estimate)),
            where,
            byte_size(round(limits.doe_bytes_per_sample)),
        )


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
        lineage=[*parent.lineage(), parent.id],
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


def mission_context(resolved: dict[str, Any], launch_fit: dict[str, Any]) -> MissionContext:
    """The context of a resolved scenario and a launch fit's coefficients, built once per
    process (a worker keeps it between batches) and rebuilt when either changes."""
    key = hashlib.sha256(
        json.dumps([resolved, launch_fit], sort_keys=True, default=str).encode()
    ).hexdigest()
    context = _CONTEXTS.get(key)
    if context is None:
        scenario = scenario_from_dict(json.loads(json.dumps(resolved)), "the batch's scenario")
        context = MissionContext(scenario, LaunchFit.from_dict(launch_fit))
        _CONTEXTS.clear()  # one scenario at a time: a worker's memory stays flat
        _CONTEXTS[key] = context
    return context


_CONTEXTS: dict[str, MissionContext] = {}


def store_batch_job(
    run_url: str,
    resolved: dict[str, Any],
    launch_fit: dict[str, Any],
    batch_index: int,
    batch: list[dict[str, float]],
    wait_s: float | None = None,
) -> dict[str, Any]:
    """One batch, evaluated and stored where the run is (:func:`store_batch`), by whatever
    process runs it: everything it needs travels with it (the run's absolute URL, the
    resolved scenario, the launch fit's coefficients, the samples as records), so a Dask
    worker needs the installed package only. Returns a small summary (the records never
    travel back); ``stored`` is None when another process holds the batch's claim for
    longer than ``wait_s`` (default: the scenario's ``mission.doe.claim_wait_s``).
    """
    start = time.perf_counter()
    context = mission_context(resolved, launch_fit)
    run = Run.open(run_url)
    scenario = context.scenario
    if wait_s is None:
        wait_s = scenario.mission.doe.claim_wait_s
    stored = store_batch(run, scenario, context, batch_index, pd.DataFrame(batch), wait_s=wait_s)
    summary: dict[str, Any] = {"batch": batch_index, "stored": stored}
    if stored is not None:
        totals = run.batch_totals(batch_index)
        summary.update(samples=len(totals), feasible=int(totals["feasible"].sum()))
    return summary | {"wall_time_s": time.perf_counter() - start}


class BatchesFailed(RuntimeError):
    """Batches raised (a lost process pool, a worker that died too often); the run's
    manifest says ``incomplete`` with their errors."""


def run_doe(
    scenario: Scenario,
    run: Run,
    launch_fit: LaunchFit,
    *,
    batch_size: int,
    progress: Callable[[str], None] | None = None,
    runner: str = "serial",
    workers: int = 1,
    dask_address: str | None = None,
    dask: DaskSettings | None = None,
    time_limit_s: float | None = None,
    on_batch: Callable[[dict[str, Any]], None] | None = None,
    pool: BatchPool | None = None,
    on_progress: Callable[[int, int, str], None] | None = None,
    job: Callable[..., dict[str, Any]] | None = None,
) -> Run:
    """Evaluate every batch the run does not hold yet and finish the manifest.

    ``runner`` (``serial | threads | processes | dask``, :mod:`ovtraj.runs.runners`) says
    where the batches run; each stores its own batch in the run. ``pool``: a pool already
    started (:func:`~ovtraj.runs.runners.batch_pool`), used instead of starting one, so
    that several runs in a row (the pipeline's DoE and infill) share its processes and
    each process's mission context (``runner``, ``workers`` and ``dask_address`` are then
    the pool's). Batches that another process is computing are left to it at first, then
    waited for (``mission.doe.claim_wait_s``); one whose process died is computed again. A
    complete run is not written to at all. ``time_limit_s`` bounds the wait for a pool's batches;
    ``on_batch`` receives each finished batch's summary (:func:`store_batch_job`).
    Messages (a line per batch) go to ``progress`` when given, else to this module's
    logger (info); ``on_progress(samples done, samples of the run, label)`` is called
    before the first batch and after each one (a progress bar's update). ``job``: what
    each batch runs, with :func:`store_batch_job`'s arguments and summary (default: it;
    ``benchmarks/scale.py`` times the orchestration with a synthetic evaluation).

    Raises :class:`ClusterError` (the manifest ends ``failed``) when the Dask cluster is
    unusable or loses every worker for ``dask.no_worker_timeout_s``, and
    :class:`BatchesFailed` (``incomplete``, the errors in ``failures``) when batches raised.
    """
    say = progress or logger.info
    batches = run.batches(batch_size)
    todo = [k for k, _ in batches if not run.is_stored(k)]
    if not todo:
        return finish(run)
    if (pool.runner if pool is not None else runner) in ("serial", "threads"):
        require_pinned_kernel()  # the batches run here: refused before the run is touched
    counted = _SampleCount(batches, todo, on_progress)
    settings = dask or load_orchestration().dask
    jobs = _BatchJobs(run, scenario, launch_fit, batches, say, settings, on_batch, counted)
    jobs.job = job or store_batch_job
    started = (
        nullcontext(pool)
        if pool is not None
        else batch_pool(runner, workers, dask_address, settings)
    )
    claim_wait_s = scenario.mission.doe.claim_wait_s
    failures = _evaluate_batches(run, jobs, started, batch_size, claim_wait_s, time_limit_s)
    finish(run)
    _raise_failures(run, failures)
    return run


def _evaluate_batches(
    run: Run,
    jobs: _BatchJobs,
    started: AbstractContextManager[BatchPool],
    batch_size: int,
    claim_wait_s: float,
    time_limit_s: float | None,
) -> dict[int, str]:
    """The run's batches evaluated on the pool ``started`` while this process works on the
    run (:meth:`Run.working`); returns the errors of the batches that failed. A
    :class:`ClusterError` leaves the run ``failed`` unless it is complete."""
    try:
        with run.working() as removed:
            if removed:
                jobs.say(f"removed {len(removed)} temporary file(s) of an interrupted write")
            run.update_manifest(batches=len(jobs.batches), batch_size=batch_size)
            with started as pool:
                return jobs.evaluate_all(pool, claim_wait_s, time_limit_s)
    except ClusterError as err:  # after `working` has said `interrupted`: the cause wins
        finish(run)
        if run.manifest.get("status") != "complete":
            run.update_manifest(status="failed", failure=f"ClusterError: {err}"[:1000])
        raise


def _raise_failures(run: Run, failures: dict[int, str]) -> None:
    """Record the failed batches in the manifest and raise :class:`BatchesFailed`; nothing
    when none failed or the run is complete all the same (another process stored them)."""
    if failures and run.manifest.get("status") != "complete":
        texts = [f"batch {k}: {why}" for k, why in sorted(failures.items())]
        run.update_manifest(failures=texts)
        raise BatchesFailed(
            f"run {run.id} incomplete: {len(failures)} batch(es) failed: {'; '.join(texts)}"
        )


class PoolBatches(StartedPool):
    """The library's :class:`ovtraj.pipeline.drive.BatchExecutor`: a run's batches on the
    pool of ``choice`` (:func:`~ovtraj.runs.runners.batch_pool`), started once for the
    DoE and every infill run, through :func:`run_doe`.

    ``progress``: a line per batch (else this module's logger); ``progress_bar(label)``: a
    context whose value is ``run_doe``'s ``on_progress`` (the CLI's bar), one per run.
    """

    def __init__(
        self,
        scenario: Scenario,
        launch_fit: LaunchFit,
        choice: RunnerChoice,
        *,
        dask: DaskSettings | None = None,
        time_limit_s: float | None = None,
        progress: Callable[[str], None] | None = None,
        progress_bar: Callable[[str], AbstractContextManager[Any]] | None = None,
    ) -> None:
        super().__init__(choice, dask or load_orchestration().dask)
        self.scenario, self.launch_fit = scenario, launch_fit
        self.time_limit_s = time_limit_s
        self.progress, self.progress_bar = progress, progress_bar

    def evaluate(self, run: Run) -> Run:
        bar = nullcontext(None) if self.progress_bar is None else self.progress_bar(f"run {run.id}")
        with bar as update:
            return run_doe(
                self.scenario,
                run,
                self.launch_fit,
                batch_size=run.batch_size(self.scenario.mission.doe),
                progress=self.progress,
                on_progress=update,
                pool=self.pool,
                dask=self.dask,
                time_limit_s=self.time_limit_s,
            )

    def side_pool(self) -> concurrent.futures.Executor | None:
        """The pool's processes (not threads: those would only share this process's
        core); on Dask bounded in time, since a cluster that lost every worker keeps
        tasks pending (the work is then done here)."""
        if self.pool is None or self.choice.runner not in ("processes", "dask"):
            return None
        if self.choice.runner == "dask":
            return Bounded(self.pool.executor, self.dask.side_work_timeout_s)
        return self.pool.executor


class _SampleCount:
    """Samples done of the run's, for ``run_doe``'s ``on_progress``."""

    def __init__(
        self,
        batches: list[tuple[int, pd.DataFrame]],
        todo: list[int],
        on_progress: Callable[[int, int, str], None] | None,
    ) -> None:
        self.sizes = {k: len(batch) for k, batch in batches}
        self.total = sum(self.sizes.values())
        self.done = self.total - sum(self.sizes[k] for k in todo)
        self.batches, self.finished = len(batches), len(batches) - len(todo)
        self.on_progress = on_progress
        self.report()

    def report(self) -> None:
        if self.on_progress is not None:
            self.on_progress(self.done, self.total, f"batch {self.finished}/{self.batches}")

    def batch_done(self, k: int) -> None:
        self.done += self.sizes[k]
        self.finished += 1
        self.report()


class _BatchJobs:
    """Submits batch jobs to a pool and collects their summaries as they end."""

    def __init__(
        self,
        run: Run,
        scenario: Scenario,
        launch_fit: LaunchFit,
        batches: list[tuple[int, pd.DataFrame]],
        say: Callable[[str], None],
        settings: DaskSettings,
        on_batch: Callable[[dict[str, Any]], None] | None = None,
        counted: _SampleCount | None = None,
    ) -> None:
        self.run, self.say, self.settings = run, say, settings
        self.pool: BatchPool | None = None  # given by :meth:`evaluate_all`
        self.batches = dict(batches)
        self.resolved, self.coefficients = scenario.resolved(), launch_fit.to_dict()
        self.failures: dict[int, str] = {}
        self.on_batch, self.counted = on_batch, counted
        self.job: Callable[..., dict[str, Any]] = store_batch_job

    def _job(self, k: int, wait_s: float) -> tuple[Any, ...]:
        records = self.batches[k].to_dict(orient="records")
        return (self.job, self.run.url, self.resolved, self.coefficients, k, records, wait_s)

    def _done(self, k: int, summary: dict[str, Any]) -> bool:
        """Report a finished job; False when another process holds the batch's claim."""
        if summary["stored"] is None:
            return False
        if self.on_batch is not None:
            self.on_batch(summary)
        if self.counted is not None:
            self.counted.batch_done(k)
        self.say(
            f"batch {k + 1}/{len(self.batches)}: {summary['samples']} samples, "
            f"{summary['feasible']} feasible, {summary['wall_time_s']:.1f} s"
            + ("" if summary["stored"] else " (already stored)")
        )
        return True

    def evaluate_all(
        self, pool: BatchPool, claim_wait_s: float, time_limit_s: float | None
    ) -> dict[int, str]:
        """Every batch not stored yet on ``pool``: those another process is computing are
        left to it at first, then waited for (``claim_wait_s``); returns the failures."""
        self.pool = pool
        todo = [k for k in self.batches if not self.run.is_stored(k)]
        waiting = self.evaluate(todo, 0.0, time_limit_s)
        for k in waiting:
            self.say(f"batch {k + 1}/{len(self.batches)}: another process is computing it; waiting")
        self.evaluate(waiting, claim_wait_s, time_limit_s)
        return self.failures

    def evaluate(self, todo: list[int], wait_s: float, time_limit_s: float | None) -> list[int]:
        """Evaluate ``todo``; returns the batches another process holds."""
        held: list[int] = []
        if self.pool.executor is None:
            for k in todo:
                function, *args = self._job(k, wait_s)
                if not self._done(k, function(*args)):
                    held.append(k)
            return held
        futures = {self.pool.executor.submit(*self._job(k, wait_s)): k for k in todo}
        deadline = None if time_limit_s is None else time.monotonic() + time_limit_s
        no_worker = self.settings.no_worker_timeout_s
        workers_gone_since: float | None = None
        while futures:
            timeout = no_worker / 10
            if deadline is not None:
                timeout = min(timeout, max(deadline - time.monotonic(), 0.0))
            finished, _ = concurrent.futures.wait(
                futures, timeout=timeout, return_when=concurrent.futures.FIRST_COMPLETED
            )
            for future in finished:
                k = futures.pop(future)
                try:
                    if not self._done(k, future.result()):
                        held.append(k)
                except Exception as err:
                    self.failures[k] = f"{type(err).__name__}: {err}"
                    self.say(f"batch {k + 1}/{len(self.batches)} failed: {self.failures[k]}")
            if not futures:
                break
            if deadline is not None and time.monotonic() >= deadline:
                for future, k in futures.items():
                    future.cancel()
                    self.failures[k] = f"not done within the DoE's limit ({time_limit_s:g} s)"
                break
            if self.pool.workers_alive():
                workers_gone_since = None
            elif workers_gone_since is None:
                workers_gone_since = time.monotonic()
            elif time.monotonic() - workers_gone_since >= no_worker:
                for future in futures:
                    future.cancel()
                raise ClusterError(
                    f"the Dask cluster has had no worker for {no_worker:g} s "
                    "(configs/orchestration.yaml dask.no_worker_timeout_s) with "
                    f"{len(futures)} batch(es) waiting: its workers died or left; see their logs"
                )
        return held


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
