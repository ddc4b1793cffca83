"""What every task shares: the cache policy, the results' expiration, the timeouts.

One cache policy object, :data:`CACHE_POLICY` = the task's inputs + the code version
(:class:`CodeVersionPolicy`), is on every task: a task run is served from Prefect's
cache only when its inputs and the code (``ovtraj.version.code_version()``: package
version, git commit, hash of uncommitted changes) are those of a stored result. No task
takes a hand-passed code version. The results' storage is set by the flows when they
submit (``flows/common.py``: ``configs/orchestration.yaml``, ``results``); the expiration
and the timeouts are set here from the same file.

The run store stays the source of truth: the tasks that write into it (DoE and Monte
Carlo batches, surrogate fits and fronts) are submitted only for what the store lacks,
and a cached result whose files are missing from the store is run again with a refreshed
cache (``flows/common.py``), so a batch is computed once, and a stored batch never.
"""

from __future__ import annotations

import datetime
import importlib
from dataclasses import dataclass
from typing import Any

from prefect.cache_policies import INPUTS, CachePolicy
from prefect.context import TaskRunContext
from prefect.utilities.hashing import hash_objects

from ovtraj.config.orchestration import OrchestrationConfig, load_orchestration

ORCHESTRATION: OrchestrationConfig = load_orchestration()


def code_version() -> str:
    """``ovtraj.version.code_version()``, looked up at each call (a test may patch it to
    simulate a code change; the package's ``version`` attribute is importlib's function
    until the submodule is imported, hence ``import_module``)."""
    return importlib.import_module("ovtraj.version").code_version()


@dataclass
class CodeVersionPolicy(CachePolicy):
    """Keyed on the code version (``ovtraj.version.code_version()``, read when the key is
    computed, so a code change is a new key) and the task's name (two tasks with the same
    inputs never share a result)."""

    def compute_key(
        self,
        task_ctx: TaskRunContext,
        inputs: dict[str, Any],
        flow_parameters: dict[str, Any],
        **kwargs: Any,
    ) -> str | None:
        name = task_ctx.task.name if task_ctx is not None else None
        return hash_objects(code_version(), name, raise_on_failure=True)


CACHE_POLICY: CachePolicy = INPUTS + CodeVersionPolicy()
# Batch tasks carry no tags: Prefect asks the server for a tag concurrency slot for every
# tagged task run (even with no limit defined), measured here at ~12 % of a worker's time
# on a 128-sample DoE (0.1 s per task, some 2.4 s); their run names hold the scenario, the
# run id and the batch instead, and the flow runs carry the tags.
BATCH_TAGS: tuple[str, ...] = ()
EXPIRATION = datetime.timedelta(hours=ORCHESTRATION.results.expiration_h)
TIMEOUTS = ORCHESTRATION.tasks


def _plain_json() -> Any:
    from tasks.results import plain_json  # imported when a task is defined

    return plain_json()


def cached(**options: Any) -> dict[str, Any]:
    """The options of a cached task: :data:`CACHE_POLICY`, persisted results that expire,
    as plain JSON (``tasks/results.py``)."""
    return {
        "cache_policy": CACHE_POLICY,
        "persist_result": True,
        "result_serializer": _plain_json(),
        "cache_expiration": EXPIRATION,
        **options,
    }


def parameter(name: str) -> Any:
    """A parameter of the task run being named (``task_run_name`` callables)."""
    from prefect.runtime import task_run

    return task_run.parameters.get(name)


def run_label(url: str | None) -> str:
    """``<run id>`` of a run URL (its last path component)."""
    return str(url or "").rstrip("/").rsplit("/", 1)[-1] or "?"
