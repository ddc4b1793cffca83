"""Where a DoE's batches run: the one runner option (``serial | threads | processes | dask``).

``ovtraj run --runner``, ``mission.doe.task_runner`` and the flows' ``runner`` parameter
name the same choices (:data:`ovtraj.config.mission.RUNNERS`). This module gives the
library's own pools for them (``concurrent.futures`` and ``distributed``, no Prefect), used
by :func:`ovtraj.runs.execute.run_doe`; the flows use Prefect's task runners of the same
names and share the Dask checks below.

- ``serial``: one batch after another in this process;
- ``threads``: a pool of ``workers`` threads (they share the GIL: ~1x);
- ``processes``: a pool of ``workers`` spawned processes (each imports and compiles once);
- ``dask``: the cluster at ``dask_address`` (workers anywhere, with ovtraj installed), or a
  local cluster of ``workers`` processes when there is none.

A batch job carries what it needs (the run's absolute URL, the resolved scenario, the
launch fit's coefficients, the samples), so a Dask worker needs the installed package
only: no checkout, no shared working folder, no launch fit on its disk.
"""

from __future__ import annotations

import concurrent.futures
import logging
import multiprocessing
import os
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Self

from ovtraj.config.io_limits import echoed
from ovtraj.config.mission import RUNNERS, DoeSettings
from ovtraj.config.orchestration import DaskSettings

logger = logging.getLogger(__name__)


class ClusterError(RuntimeError):
    """The Dask cluster cannot run the batches (unreachable, no worker, bad worker)."""


DASK_ADDRESS_ENV = "OVTRAJ_DASK_ADDRESS"
"""The Dask scheduler when neither the command line nor the flow names one (never
a scenario file, which is shared; Dask's protocol unpickles what the scheduler sends)."""


def dask_address(given: str | None) -> str | None:
    """The scheduler of the ``dask`` runner: ``given`` (``--dask-address``, the flow's
    parameter), else :data:`DASK_ADDRESS_ENV`; ``None``: a local cluster."""
    return given or os.environ.get(DASK_ADDRESS_ENV) or None


@dataclass(frozen=True)
class RunnerChoice:
    """Where a DoE's batches run: the runner, its pool's size, the Dask scheduler (None:
    a local cluster, or no Dask)."""

    runner: str
    workers: int
    dask_address: str | None = None


def choose_runner(
    settings: DoeSettings,
    runner: str | None = None,
    given_address: str | None = None,
    *,
    as_options: bool = False,
) -> RunnerChoice:
    """The one runner choice of the CLI and the flows: ``runner`` (the option or the flow's
    parameter), else ``mission.doe.task_runner``; the scheduler :func:`dask_address`.

    A bad choice raises ``ValueError`` naming it: as the CLI's options with
    ``as_options`` (``--runner``, ``--dask-address``), else as the flows' parameters.
    """
    chosen = runner or settings.task_runner
    if as_options:
        if chosen not in RUNNERS:
            shown = echoed(repr(chosen))
            raise ValueError(f"--runner {shown}: must be one of {', '.join(RUNNERS)}")
        if given_address and chosen != "dask":
            raise ValueError(f"--dask-address needs --runner dask (the runner is {chosen})")
    address = dask_address(given_address) if chosen == "dask" else given_address
    check_runner(chosen, address)
    return RunnerChoice(chosen, settings.workers, address)


def check_runner(runner: str, dask_address: str | None = None) -> None:
    """Refuse an unknown runner name, or an address without the ``dask`` runner."""
    if runner not in RUNNERS:
        raise ValueError(f"runner = {runner!r}: must be one of {', '.join(RUNNERS)}")
    if dask_address and runner != "dask":
        raise ValueError(f"dask_address = {dask_address!r} needs runner = dask, not {runner}")


def limit_threads(threads: int | None) -> dict[str, Any]:
    """Limit this process's thread pools (BLAS/OpenMP through threadpoolctl, heyoka's TBB)
    to ``threads``: one evaluation per core, no pool competing with the other workers'
    (docs/mission.md, measured). ``None`` leaves the libraries' own (a thread per core)."""
    if threads is None:
        return {}
    import heyoka
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=threads)  # process-wide, kept after this call
    heyoka.set_nthreads(threads)
    return {"threads": threads}


def check_worker(
    threads: int | None = None, profiler: bool = True, dask_worker: Any = None
) -> dict[str, Any]:
    """Run on every Dask worker by :func:`check_cluster`: can it import and run ovtraj,
    and which OpenBLAS kernels does it run (``blas_kernels``; ``blas_problem``: the
    worker's own :func:`ovtraj.environment.check`)?

    When it can, the worker is set up for evaluations (:func:`limit_threads`, and Dask's
    statistical profiler stopped unless ``profiler``: it samples the task thread's stack
    every 10 ms). ``dask_worker`` is given by ``Client.run``. Shipped by value to the
    worker (it must answer even where ovtraj is missing), so it imports inside.
    """
    import importlib
    import os
    import sys

    try:
        import ovtraj

        importlib.import_module("ovtraj.runs.execute")  # the modules a batch job needs

        version = importlib.import_module("ovtraj.version")
        runners = importlib.import_module("ovtraj.runs.runners")
        environment = importlib.import_module("ovtraj.environment")
    except Exception as err:  # any failure is the answer
        return {"ok": False, "error": f"{type(err).__name__}: {err}", "python": sys.executable}
    tuned = runners.limit_threads(threads)
    if not profiler and dask_worker is not None:
        for name in ("profile", "profile-cycle"):
            callback = dask_worker.periodic_callbacks.get(name)
            if callback is not None:
                callback.stop()
        tuned["profiler"] = "stopped"
    return {
        "ok": True,
        "ovtraj": ovtraj.__version__,
        "code": version.code_version(),
        "pid": os.getpid(),
        "cwd": os.getcwd(),
        "name": None if dask_worker is None else str(dask_worker.name),
        "blas_kernels": sorted(
            {
                str(lib["architecture"])
                for lib in environment.blas_libraries()
                if lib["internal_api"] == "openblas"
            }
        ),
        "blas_problem": environment.check(),
        **tuned,
    }


def check_cluster(client: Any, where: str, settings: DaskSettings) -> dict[str, dict[str, Any]]:
    """Wait for a worker, then ask every worker whether it imports ovtraj (and set it up
    for evaluations: :func:`check_worker`), all within ``settings.connect_timeout_s``.

    Raises :class:`ClusterError` naming the cluster, the workers and the cause when no
    worker comes in time, a worker cannot import the project (such a worker would exit
    on the first task it deserialises and leave the run waiting), or a worker runs another
    OpenBLAS kernel than this process's pin (it would store other last bits under the same
    run id: :mod:`ovtraj.environment`; a ``dask worker`` started by hand loads numpy before
    ovtraj can pin, so it needs ``OPENBLAS_CORETYPE`` in its environment). Logs each
    worker's kernels.
    """
    import cloudpickle

    timeout_s = settings.connect_timeout_s
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except Exception as err:
        raise ClusterError(
            f"Dask cluster at {where}: no worker after {timeout_s:g} s "
            f"(configs/orchestration.yaml dask.connect_timeout_s): {type(err).__name__}"
        ) from None
    module = sys.modules[__name__]
    registered = __name__ in cloudpickle.list_registry_pickle_by_value()
    if not registered:
        cloudpickle.register_pickle_by_value(module)  # answered where ovtraj is missing
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=1)
    try:
        answers = pool.submit(
            client.run,
            check_worker,
            settings.worker_threads,
            settings.worker_profiler,
            on_error="return",
        ).result(timeout_s)
    except concurrent.futures.TimeoutError:
        raise ClusterError(
            f"Dask cluster at {where}: the workers did not answer within {timeout_s:g} s "
            "(configs/orchestration.yaml dask.connect_timeout_s)"
        ) from None
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
        if not registered:
            cloudpickle.unregister_pickle_by_value(module)
    bad = {}
    for worker, answer in sorted(answers.items()):
        if isinstance(answer, BaseException):
            bad[worker] = f"{type(answer).__name__}: {answer}"
        elif not answer.get("ok"):
            bad[worker] = f"{answer['error']} (python {answer.get('python')})"
    if bad:
        listing = "; ".join(f"{worker}: {why}" for worker, why in bad.items())
        raise ClusterError(
            f"Dask cluster at {where}: {len(bad)} of {len(answers)} worker(s) cannot import "
            f"the project ({listing}); install ovtraj in the workers' environment"
        )
    _check_kernels(answers, where)
    return answers


def _check_kernels(answers: dict[str, dict[str, Any]], where: str) -> None:
    """Refuse workers whose OpenBLAS runs another kernel than this process's pin, or that
    refuse to compute themselves (:func:`check_worker`'s ``blas_problem``)."""
    from ovtraj.environment import CORETYPE_ENV, pin

    wanted = pin().kernel
    off = {}
    for address, answer in sorted(answers.items()):
        named = answer.get("name")
        worker = address if named in (None, address) else f"{address} ({named})"
        kernels = answer.get("blas_kernels") or []
        logger.info("Dask worker %s: OpenBLAS kernel %s", worker, ", ".join(kernels) or "none")
        other = [k for k in kernels if wanted is not None and k.lower() != wanted.lower()]
        if other:
            off[worker] = f"OpenBLAS runs the {', '.join(other)} kernel, not {wanted}"
        elif answer.get("blas_problem"):
            off[worker] = str(answer["blas_problem"])
    if off:
        listing = "; ".join(f"{worker}: {why}" for worker, why in off.items())
        fix = f"{CORETYPE_ENV}={wanted}" if wanted is not None else "the same OpenBLAS kernel"
        raise ClusterError(
            f"Dask cluster at {where}: {len(off)} of {len(answers)} worker(s) would store other "
            f"last bits ({listing}); start each `dask worker` with {fix} in its environment "
            "(docs/mission.md, 'Reproducibility')"
        )


def count_workers(client: Any) -> int:
    """The workers the scheduler knows now (0 when it cannot be asked)."""
    try:
        return len(client.scheduler_info(n_workers=-1).get("workers", {}))
    except Exception:
        return 0


def connect(address: str | None, workers: int, settings: DaskSettings) -> Any:
    """A checked ``distributed.Client``: of the cluster at ``address``, else of a new local
    cluster of ``workers`` processes (``settings.threads_per_worker`` threads each)."""
    from distributed import Client, LocalCluster

    if address:
        try:
            client = Client(address, timeout=settings.connect_timeout_s)
        except OSError as err:
            raise ClusterError(
                f"Dask cluster at {address}: cannot reach the scheduler within "
                f"{settings.connect_timeout_s:g} s (configs/orchestration.yaml "
                f"dask.connect_timeout_s): {err}"
            ) from None
        except (TypeError, ValueError) as err:  # e.g. tls:// without Dask's TLS settings
            raise ClusterError(
                f"Dask cluster at {address}: cannot connect ({err}); a tls:// scheduler "
                "needs Dask's TLS settings (docs/mission.md, 'A TLS-secured cluster')"
            ) from None
    else:
        cluster = LocalCluster(
            n_workers=workers,
            processes=True,
            threads_per_worker=settings.threads_per_worker,
            dashboard_address=None,
        )
        client = Client(cluster)
    try:
        check_cluster(client, address or "a local cluster", settings)
    except BaseException:
        close(client)
        raise
    return client


def close(client: Any) -> None:
    """Close a client (and the local cluster it started; an existing one stays up)."""
    cluster = getattr(client, "cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()


@dataclass
class BatchPool:
    """A started pool: ``executor`` (None: serial, here) and the Dask client if any."""

    runner: str
    executor: concurrent.futures.Executor | None
    client: Any = None

    def workers_alive(self) -> bool:
        """False only when a Dask cluster has no worker left."""
        return self.client is None or count_workers(self.client) > 0


@contextmanager
def batch_pool(
    runner: str, workers: int, dask_address: str | None, settings: DaskSettings
) -> Iterator[BatchPool]:
    """The started pool of ``runner`` (a Dask cluster checked first, :func:`connect`)."""
    check_runner(runner, dask_address)
    if runner == "serial":
        yield BatchPool(runner, None)
    elif runner == "threads":
        from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads

        # process-wide, so set for the pool's life: a batch's own limit, restored when it
        # ends, would otherwise lift it under a batch still running in another thread
        with (
            blas_threads(EVALUATION_BLAS_THREADS),
            concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool,
        ):
            yield BatchPool(runner, pool)
    elif runner == "processes":
        # spawn, not fork: a forked child would inherit the integrators' thread pools
        # mid-state; each process sets its pools like a Dask worker's.
        with concurrent.futures.ProcessPoolExecutor(
            max_workers=workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=limit_threads,
            initargs=(settings.worker_threads,),
        ) as pool:
            yield BatchPool(runner, pool)
    else:
        client = connect(dask_address, workers, settings)
        try:
            yield BatchPool(runner, client.get_executor(pure=False), client)
        finally:
            close(client)


class StartedPool:
    """The pool of ``choice`` (:func:`batch_pool`) as ``self.pool``: started on enter, shut
    on exit. The DoE's batches (:class:`~ovtraj.runs.execute.PoolBatches`) and a Monte
    Carlo's (:class:`~ovtraj.runs.monte_carlo_pool.PoolFlier`) run on it; ``dask`` must be
    set before enter."""

    def __init__(self, choice: RunnerChoice, dask: DaskSettings | None) -> None:
        self.choice, self.dask = choice, dask
        self._stack = ExitStack()
        self.pool: BatchPool | None = None

    def __enter__(self) -> Self:
        choice = self.choice
        self.pool = self._stack.enter_context(
            batch_pool(choice.runner, choice.workers, choice.dask_address, self.dask)
        )
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self.pool = None
        self._stack.close()
