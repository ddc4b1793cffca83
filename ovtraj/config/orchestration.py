"""How the Prefect flows run: timeouts, Dask checks, task results, concurrency.

``configs/orchestration.yaml`` (shipped; ``OVTRAJ_CONFIG_DIR`` moves it). These settings
belong to no scenario: they never change a result or a run id, and a stored run's
``config.json`` does not carry them. The flows (``flows/``) read them when imported; the
library reads only ``reads`` (at its first read of a store file), ``store_key`` (when
``OVTRAJ_STORE_KEY`` is set, :mod:`ovtraj.store.seals`) and ``preparation`` (when a DoE or a
pipeline is prepared, :mod:`ovtraj.runs.preparation`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from pydantic import Field

from ovtraj.config.base import StrictModel, bounded, load_model
from ovtraj.paths import config_path, workspace

FILE = "orchestration.yaml"
# Overrides results.storage (a folder or an fsspec URL): the tests' own result storage.
RESULTS_ENV = "OVTRAJ_PREFECT_RESULTS"


class TaskTimeouts(StrictModel):
    """Prefect ``timeout_seconds`` of every task."""

    mission_batch_per_sample_s: float = bounded(
        unit="s", gt=0, le=86400, description="a DoE batch task: this times its samples"
    )
    rendezvous_s: float = bounded(unit="s", gt=0, le=86400)
    launch_point_s: float = bounded(unit="s", gt=0, le=86400)
    deorbit_mc_batch_per_run_s: float = bounded(
        unit="s", gt=0, le=86400, description="a Monte Carlo batch task: this times its runs"
    )
    mission_mc_batch_per_run_s: float = bounded(
        unit="s", gt=0, le=86400, description="a plan Monte Carlo batch: this times its runs"
    )
    fit_surrogates_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    surrogate_front_s: float = bounded(unit="s", gt=0, le=86400)


class FlowTimeouts(StrictModel):
    """Wall-time limit of each flow run."""

    rendezvous_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    launch_fit_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    doe_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    deorbit_monte_carlo_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    mission_monte_carlo_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    surrogate_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    optimize_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    mission_s: float = bounded(unit="s", gt=0, le=7 * 86400)


class DaskSettings(StrictModel):
    """The ``dask`` runner: checks of the cluster, and a local cluster's shape."""

    connect_timeout_s: float = bounded(
        unit="s",
        gt=0,
        le=3600,
        description="reach the scheduler, wait for a worker, check every worker imports ovtraj",
    )
    no_worker_timeout_s: float = bounded(
        unit="s", gt=0, le=86400, description="batches waiting on a cluster with no worker"
    )
    side_work_timeout_s: float = bounded(
        unit="s",
        gt=0,
        le=86400,
        description="the pipeline's surrogate scoring and plots on the cluster: past this, "
        "this process does them",
    )
    threads_per_worker: int = bounded(ge=1, le=256, description="of a local cluster")
    worker_threads: int | None = bounded(
        ge=1,
        le=256,
        description="thread pools (BLAS/OpenMP, heyoka's TBB) of each worker, set when the "
        "flow connects; null: the libraries' own (one per core)",
    )
    worker_profiler: bool = Field(
        description="leave Dask's statistical profiler running in the workers (false: stopped "
        "when the flow connects)"
    )


class ResultSettings(StrictModel):
    """Prefect's task results: where they are stored and how long they are served."""

    storage: str | None = Field(
        description="a folder (relative: to the workspace) or an fsspec URL; null: "
        "<workspace>/prefect-results"
    )
    expiration_h: float = bounded(unit="h", gt=0, le=10 * 8760)

    def location(self) -> str:
        """The storage as an absolute folder or a URL (``OVTRAJ_PREFECT_RESULTS`` first)."""
        chosen = os.environ.get(RESULTS_ENV) or self.storage
        if chosen is None:
            return str(workspace() / "prefect-results")
        if "://" in chosen:
            return chosen
        path = Path(chosen).expanduser()
        return str(path if path.is_absolute() else (workspace() / path).resolve())


class ConcurrencySettings(StrictModel):
    """The global concurrency limit per run id (one flow run evaluates a run at a time)."""

    run_slot_wait_s: float = bounded(unit="s", gt=0, le=7 * 86400)
    lease_s: float = bounded(unit="s", ge=60, le=86400, description="renewed while held")


class ReadSettings(StrictModel):
    """Checked reads of the stores (:mod:`ovtraj.store.files`)."""

    decoded_tables_mib: float = bounded(
        unit="MiB",
        ge=0,
        le=1024 * 1024,
        description="Arrow memory kept of the decoded Parquet files, reused for the same bytes",
    )
    stored_file_max_mib: float = bounded(
        unit="MiB",
        gt=0,
        le=1024 * 1024,
        description="largest size a marker may record for a stored file: a larger (or "
        "non-integer, negative) recorded size is refused, naming the marker",
    )
    unrecorded_file_max_mib: float = bounded(
        unit="MiB",
        gt=0,
        le=64 * 1024,
        description="largest file read without a recorded size (a manifest, a marker, a "
        "Prefect result record `ovtraj prune` parses)",
    )
    environment_block_max_kib: float = bounded(
        unit="KiB",
        gt=0,
        le=1024,
        description="largest environment block of a manifest or marker, as JSON "
        "(ovtraj/store/environment_block.py): a larger one is refused, naming the file",
    )


class CatalogSettings(StrictModel):
    """The store's catalog and its queries (:mod:`ovtraj.tracking.catalog`)."""

    lock_wait_s: float = bounded(unit="s", gt=0, le=3600, description="wait for a refresh")
    query_time_limit_s: float = bounded(
        unit="s", gt=0, le=3600, description="a --where query is interrupted past this"
    )
    where_max_chars: int = bounded(unit="characters", ge=16, le=100_000)
    query_memory_mib: int = bounded(
        unit="MiB", ge=16, le=65_536, description="address space a --where query may add"
    )
    query_threads: int = bounded(unit="threads", ge=1, le=64)
    tags_per_item: int = bounded(unit="tags", ge=1, le=1000)
    tag_key_max_chars: int = bounded(unit="characters", ge=1, le=256)
    tag_value_max_chars: int = bounded(unit="characters", ge=1, le=4096)
    rows_shown: int = bounded(unit="rows", ge=1, le=1_000_000)


class StoreKeySettings(StrictModel):
    """The key of the stores' seals (:mod:`ovtraj.store.seals`), given by ``OVTRAJ_STORE_KEY``."""

    min_bytes: int = bounded(
        unit="bytes",
        ge=16,
        le=1024,
        description="a shorter key is refused (HMAC-SHA256: at least its 32-byte output)",
    )


class LockSettings(StrictModel):
    """The store's locks (:mod:`ovtraj.store.locks`)."""

    poll_s: float = bounded(unit="s", gt=0, le=10, description="a held lock is tried again after")
    lease_s: float = bounded(
        unit="s",
        ge=5,
        le=3600,
        description="an object-store lease unrenewed this long is stale (renewed each third)",
    )


class PreparationSettings(StrictModel):
    """What a DoE or a pipeline does before its first batch, from the command line and the
    flows alike (:mod:`ovtraj.runs.preparation`)."""

    launch_fit: Literal["fit", "require"] = Field(
        description="a scenario with no stored launch fit: `fit` solves and stores it first "
        "(the command in its process, a flow as the launch-fit subflow); `require` refuses, "
        "naming the command that fits it"
    )


class OrchestrationConfig(StrictModel):
    tasks: TaskTimeouts
    flows: FlowTimeouts
    dask: DaskSettings
    results: ResultSettings
    concurrency: ConcurrencySettings
    reads: ReadSettings
    catalog: CatalogSettings
    store_key: StoreKeySettings
    locks: LockSettings
    preparation: PreparationSettings


def load_orchestration(path: str | Path | None = None) -> OrchestrationConfig:
    """``configs/orchestration.yaml`` (or ``path``); errors name the file and the field."""
    return load_model(OrchestrationConfig, path or config_path(FILE))
