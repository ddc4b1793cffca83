"""DoE scaling on a Dask cluster of real worker processes: one worker against two.

A ``samples``-sample DoE of the default scenario runs through ``flows/doe.py:doe_flow``
(``runner="dask"``: "flow"), and through what ``ovtraj run --runner dask`` does (the
library's pool, no Prefect: "command"), on a warm cluster started here: a ``dask
scheduler`` and two ``dask worker`` processes (``--nthreads 1`` each; every process in a
folder of its own, without the checkout on its path), using one worker (a Dask
restriction, the other idle) or both, against a temporary Prefect server. Each repetition
runs the four cases once into fresh stores (nothing cached), the order reversed every
other repetition. Measured per run: the wall time of the call, every sample's evaluation
time (inside the tasks, from the batch markers), the tasks' summed time (evaluation and
storing) and the CPU time each process used (the Prefect server, the Dask scheduler and
workers, this process, and the rest of the machine). The medians over the repetitions are
reported; the VM is shared and noisy.

- ``speedup_2_workers`` = median wall on one worker / median wall on two;
- ``overhead`` (two workers) = (workers x wall - summed evaluation time) / summed
  evaluation time: the time the workers were not evaluating, against the evaluation;
- the evaluation medians on one and on two workers, and serially in this process (the
  library path, ``--serial-samples``), show whether a sample gets slower in parallel.

Goals: speed-up >= 1.7 on two workers, overhead < 10 %.

Batches of 64 by default: a task of 64 samples lasts ~5 s, as a batch of 32 did before
the mission chain's evaluation was made 1.9x faster. Each task run has a fixed cost of 0.2-0.5 s in
the worker (Prefect's settings and TLS contexts, docs/mission.md); with batches of 32 on
the faster chain (~2.8 s tasks) the flow measured a speed-up of 1.62 and an overhead of
10.7 %, the command 1.89 and 4.5 %.

Run: ``python benchmarks/doe.py [--samples 256] [--batch 64] [--repeats 3] [--json]
[--worker-threads N|default] [--serial-samples 32]``. ``--worker-threads`` sets the thread
pools of the workers (OMP/OpenBLAS/MKL/numba/heyoka's TBB) through their environment;
``default`` leaves the libraries' own choice (one thread per core). ``--json`` prints
only the JSON object (otherwise the table, then that object as the last line).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml
from goals import goal

from ovtraj.environment import CORETYPE_ENV, pin

os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DASK = Path(sys.executable).with_name("dask")
SPEEDUP_GOAL = goal("doe", "speedup")  # the scaling goal: two workers against one
OVERHEAD_GOAL = goal("doe", "overhead")  # orchestration over evaluation time, under
START_TIMEOUT_S = 120.0
VIAS = ("flow", "command")  # the Prefect DoE flow; `ovtraj run --runner dask` (the library)


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--batch", type=int, default=64, help="samples per task")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--worker-setup",
        choices=("config", "default"),
        default="config",
        help="config: the workers set up by the flow (configs/orchestration.yaml dask."
        "worker_threads, worker_profiler); default: as `dask worker` starts them",
    )
    parser.add_argument(
        "--task-tags",
        action="store_true",
        help="tag the batch task runs (the shipped flow does not: each tagged run asks the "
        "server for tag concurrency slots)",
    )
    parser.add_argument("--serial-samples", type=int, default=32)
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    return parser.parse_args()


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class Cluster:
    """``dask scheduler`` and ``workers`` ``dask worker`` processes, each a process group
    in its own folder; stopped by their PIDs."""

    def __init__(self, root: Path, name: str, workers: int) -> None:
        self.name, self.workers = name, workers
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.processes: list[subprocess.Popen] = []
        env = {
            k: v
            for k, v in os.environ.items()
            if not k.startswith(("PYTHONPATH", "PREFECT_", "OVTRAJ_"))
        }
        env["PREFECT_SERVER_ANALYTICS_ENABLED"] = "false"
        if pin().kernel is not None:  # a worker loads numpy before ovtraj can pin its kernel
            env[CORETYPE_ENV] = pin().kernel
        self.env = env
        scheduler = [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(self.port)]
        self._start(root / f"{name}-scheduler", [*scheduler, "--no-dashboard"])
        for k in range(workers):
            worker = [str(DASK), "worker", self.address, "--nthreads", "1", "--no-dashboard"]
            self._start(root / f"{name}-worker-{k}", [*worker, "--name", f"{name}-{k}"])

    def _start(self, folder: Path, command: list[str]) -> None:
        folder.mkdir(parents=True)
        with open(folder / "process.log", "wb") as log:
            self.processes.append(
                subprocess.Popen(
                    command,
                    cwd=folder,
                    env=self.env,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,
                )
            )

    def wait(self) -> None:
        from distributed import Client

        started = time.monotonic()
        while True:
            try:
                with Client(self.address, timeout=10) as client:
                    client.wait_for_workers(self.workers, timeout=START_TIMEOUT_S)
                    return
            except OSError:
                if time.monotonic() - started > START_TIMEOUT_S:
                    raise
                time.sleep(0.5)

    def pids(self) -> dict[str, list[int]]:
        """The scheduler's and each worker's processes (a worker: nanny and child)."""
        import psutil

        out = {}
        for k, process in enumerate(self.processes):
            role = "scheduler" if k == 0 else f"worker {k}"
            try:
                tree = psutil.Process(process.pid)
                out[role] = [process.pid, *(c.pid for c in tree.children(recursive=True))]
            except psutil.NoSuchProcess:
                continue
        return out

    def worker_addresses(self) -> list[str]:
        """The workers' addresses, in the order of their names."""
        from distributed import Client

        with Client(self.address, timeout=10) as client:
            workers = client.scheduler_info(n_workers=-1)["workers"]
        return [a for a, _ in sorted(workers.items(), key=lambda item: item[1]["name"])]

    def stop(self) -> None:
        for process in reversed(self.processes):
            try:
                os.killpg(process.pid, signal.SIGTERM)
                process.wait(timeout=30)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                try:
                    os.killpg(process.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass


def _cpu_seconds(pids: list[int]) -> float:
    import psutil

    total = 0.0
    for pid in pids:
        try:
            times = psutil.Process(pid).cpu_times()
            total += times.user + times.system
        except psutil.NoSuchProcess:
            continue
    return total


def _server_pids() -> list[int]:
    """The temporary Prefect server: this process's children that are not Dask's."""
    import psutil

    me = psutil.Process()
    return [
        child.pid
        for child in me.children(recursive=True)
        if "dask" not in " ".join(child.cmdline()) and "spawn_main" not in " ".join(child.cmdline())
    ]


def _command_doe(config: Path, store: Path, address: str) -> dict:
    """What ``ovtraj run CONFIG --store STORE --runner dask --dask-address ADDRESS`` does
    (the library's pool, no Prefect), in this process; the run's summary with the summed
    time of its batch jobs."""
    from ovtraj.config.orchestration import load_orchestration
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.runs import RunStore, prepare_run, run_doe
    from ovtraj.target_sources import load_scenario
    from ovtraj.version import code_version

    scenario = load_scenario(config)
    settings = scenario.mission.doe
    run = prepare_run(
        scenario,
        samples=settings.samples,
        seed=settings.seed,
        code=code_version(),
        store=RunStore(store),
    )
    jobs: list[dict] = []
    run_doe(
        scenario,
        run,
        find_launch_fit(scenario),
        batch_size=settings.batch_size,
        runner="dask",
        dask_address=address,
        dask=load_orchestration().dask,
        on_batch=jobs.append,
    )
    return run.summary() | {"task_time_s": sum(job["wall_time_s"] for job in jobs)}


def _timed_run(config: Path, store: Path, cluster: Cluster, workers: int, via: str) -> dict:
    """One DoE on the cluster's first ``workers`` workers (the others idle: a Dask
    restriction, ``dask.annotate(workers=...)``), through the flow or the command."""
    import dask
    import psutil

    from flows.doe import run_doe_flow
    from ovtraj.runs import RunStore

    groups = {"Prefect server": _server_pids(), "this process (flow or command)": [os.getpid()]}
    for role, pids in cluster.pids().items():
        groups[f"Dask {role}"] = pids
    before = {k: _cpu_seconds(v) for k, v in groups.items()}
    machine = psutil.cpu_times()
    start = time.perf_counter()
    with dask.annotate(workers=cluster.worker_addresses()[:workers]):
        if via == "flow":
            summary = run_doe_flow(
                config=str(config),
                store=str(store),
                runner="dask",
                dask_address=cluster.address,
            )
        else:
            summary = _command_doe(config, store, cluster.address)
    wall = time.perf_counter() - start
    machine_after = psutil.cpu_times()
    cpu = {k: _cpu_seconds(v) - before[k] for k, v in groups.items()}
    busy = (machine_after.user + machine_after.system) - (machine.user + machine.system)
    cpu["rest of the machine"] = max(busy - sum(cpu.values()), 0.0)
    run = RunStore(store).run(summary["run_id"])
    evaluations = [
        float(t)
        for marker in run.markers().values()
        for t in marker["timing"]["sample_wall_time_s"].values()
    ]
    assert summary["status"] == "complete" and len(evaluations) == summary["samples"]
    return {
        "wall_s": wall,
        "evaluations_s": evaluations,
        "task_s": summary["task_time_s"],
        "cpu_s": cpu,
    }


def _serial_median(config: Path, samples: int) -> float:
    """Median evaluation of ``samples`` samples in this process (the library path)."""
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, evaluate
    from ovtraj.runs import latin_hypercube
    from ovtraj.target_sources import load_scenario

    scenario = load_scenario(config)
    context = MissionContext(scenario, find_launch_fit(scenario))
    designs = latin_hypercube(scenario.mission.design_bounds, samples + 2, seed=1)
    times = []
    for k, row in enumerate(designs.itertuples(index=False)):
        design = MissionDesign(**{n: float(getattr(row, n)) for n in DESIGN_NAMES})
        start = time.perf_counter()
        evaluate(context, design)
        if k >= 2:  # the first two compile
            times.append(time.perf_counter() - start)
    return statistics.median(times)


def _variant(args: argparse.Namespace) -> None:
    """The measured variants: workers as ``dask worker`` starts them (no thread limits,
    profiler on) instead of as the flow sets them up; tagged batch task runs."""
    import flows.doe
    import flows.runners

    if args.worker_setup == "default":
        settings = flows.runners.ORCHESTRATION
        dask = settings.dask.model_copy(update={"worker_threads": None, "worker_profiler": True})
        flows.runners.ORCHESTRATION = settings.model_copy(update={"dask": dask})
    if args.task_tags:
        tagged = flows.doe.mission_batch_task.with_options(tags=["ovtraj", "doe", "benchmark"])
        flows.doe.mission_batch_task = tagged


def _summary(runs: list[dict], workers: int) -> dict[str, float]:
    walls = [r["wall_s"] for r in runs]
    overheads = [(workers * r["wall_s"] - r["task_s"]) / r["task_s"] for r in runs]
    beyond_evaluation = [
        (workers * r["wall_s"] - sum(r["evaluations_s"])) / sum(r["evaluations_s"]) for r in runs
    ]
    medians = [statistics.median(r["evaluations_s"]) for r in runs]
    cpu = {k: statistics.median(r["cpu_s"][k] for r in runs) for k in runs[0]["cpu_s"]}
    return {
        "wall_s": statistics.median(walls),
        "wall_range_s": [min(walls), max(walls)],
        "evaluation_median_s": statistics.median(medians),
        "evaluation_sum_s": statistics.median(sum(r["evaluations_s"]) for r in runs),
        "task_sum_s": statistics.median(r["task_s"] for r in runs),
        "overhead": statistics.median(overheads),
        "overhead_range": [min(overheads), max(overheads)],
        "overhead_vs_evaluation": statistics.median(beyond_evaluation),
        "cpu_s": cpu,
    }


def main() -> None:
    args = _arguments()
    say = (lambda *_: None) if args.json else print
    from prefect.testing.utilities import prefect_test_harness

    from flows.doe import run_doe_flow

    _variant(args)
    workdir = Path(tempfile.mkdtemp(prefix="ovtraj-doe-bench-"))
    os.environ["OVTRAJ_PREFECT_RESULTS"] = str(workdir / "task-results")
    data = yaml.safe_load((ROOT / "configs" / "scenario.yaml").read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(ROOT / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(
        samples=args.samples, batch_size=args.batch, task_runner="dask", task_retries=0
    )
    config = workdir / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    serial = _serial_median(config, args.serial_samples) if args.serial_samples else None
    cluster: Cluster | None = None
    results: dict[tuple[str, int], list[dict]] = {
        (via, workers): [] for via in VIAS for workers in (1, 2)
    }
    try:
        # The cluster's processes start while the Prefect server does (each takes seconds).
        cluster = Cluster(workdir, "cluster", 2)
        with prefect_test_harness(server_startup_timeout=120):
            cluster.wait()
            # Warm-up: both workers import, compile and evaluate (batches of 2).
            run_doe_flow(
                config=str(config),
                samples=8,
                store=str(workdir / "warm-up"),
                runner="dask",
                dask_address=cluster.address,
            )
            for rep in range(args.repeats):
                order = [(v, w) for v in VIAS for w in (1, 2)]
                for via, workers in order if rep % 2 == 0 else order[::-1]:
                    store = workdir / f"timed-{via}-{workers}-{rep}"
                    run = _timed_run(config, store, cluster, workers, via)
                    results[via, workers].append(run)
                    say(
                        f"  run {rep}  {via:7}  {workers} worker(s)  wall {run['wall_s']:6.1f} s"
                        f"  evaluation median {statistics.median(run['evaluations_s']):.3f} s"
                    )
    finally:
        if cluster is not None:
            cluster.stop()
    summaries = {key: _summary(runs, key[1]) for key, runs in results.items()}
    one, two = summaries["flow", 1], summaries["flow", 2]
    speedup = one["wall_s"] / two["wall_s"]
    command_one, command_two = summaries["command", 1], summaries["command", 2]
    command_speedup = command_one["wall_s"] / command_two["wall_s"]
    report = {
        "samples": args.samples,
        "batch_size": args.batch,
        "repeats": args.repeats,
        "worker_setup": args.worker_setup,
        "task_tags": args.task_tags,
        "speedup_2_workers": round(speedup, 3),
        "speedup_goal": SPEEDUP_GOAL,
        "speedup_ratio": round(speedup / SPEEDUP_GOAL, 3),
        "overhead": round(two["overhead"], 4),
        "overhead_goal": OVERHEAD_GOAL,
        "overhead_ratio": round(two["overhead"] / OVERHEAD_GOAL, 3),
        "speedup_2_workers_command": round(command_speedup, 3),
        "speedup_ratio_command": round(command_speedup / SPEEDUP_GOAL, 3),
        "overhead_command": round(command_two["overhead"], 4),
        "overhead_ratio_command": round(command_two["overhead"] / OVERHEAD_GOAL, 3),
        "overhead_1_worker": round(one["overhead"], 4),
        "overhead_vs_evaluation_2_workers": round(two["overhead_vs_evaluation"], 4),
        "overhead_vs_evaluation_1_worker": round(one["overhead_vs_evaluation"], 4),
        "wall_1_worker_s": round(one["wall_s"], 2),
        "wall_2_workers_s": round(two["wall_s"], 2),
        "wall_1_worker_command_s": round(command_one["wall_s"], 2),
        "wall_2_workers_command_s": round(command_two["wall_s"], 2),
        "evaluation_median_serial_s": None if serial is None else round(serial, 4),
        "evaluation_median_1_worker_s": round(one["evaluation_median_s"], 4),
        "evaluation_median_2_workers_s": round(two["evaluation_median_s"], 4),
        "cpu_s_1_worker": {k: round(v, 1) for k, v in one["cpu_s"].items()},
        "cpu_s_2_workers": {k: round(v, 1) for k, v in two["cpu_s"].items()},
    }
    say(
        f"\nDoE of {args.samples} samples, batches of {args.batch}, on a Dask cluster of two "
        f"worker processes (--nthreads 1; set up: {args.worker_setup}; task tags: "
        f"{'yes' if args.task_tags else 'no'}), one of them or both, through the Prefect flow "
        f"and through `ovtraj run --runner dask` (command); medians of {args.repeats} runs each"
    )
    columns = [("flow", 1), ("flow", 2), ("command", 1), ("command", 2)]
    say(f"  {'':38}" + "".join(f"{f'{v} {w}w':>12}" for v, w in columns))
    for label, key, fmt in (
        ("wall [s]", "wall_s", "{:12.1f}"),
        ("evaluation median [s]", "evaluation_median_s", "{:12.3f}"),
        ("evaluation summed [s]", "evaluation_sum_s", "{:12.1f}"),
        ("tasks summed (evaluate + store) [s]", "task_sum_s", "{:12.1f}"),
        ("overhead (vs the tasks)", "overhead", "{:12.1%}"),
        ("overhead (vs the evaluations)", "overhead_vs_evaluation", "{:12.1%}"),
    ):
        say(f"  {label:38}" + "".join(fmt.format(summaries[c][key]) for c in columns))
    for name in two["cpu_s"]:
        say(
            f"  {'CPU [s] ' + name:38}"
            + "".join(f"{summaries[c]['cpu_s'].get(name, 0.0):12.1f}" for c in columns)
        )
    if serial is not None:
        say(f"  evaluation median, serial in this process: {serial:.3f} s")
    for via, rate, extra in (("flow", speedup, two), ("command", command_speedup, command_two)):
        say(
            f"  {via}: speed-up on 2 workers {rate:.2f} (goal >= {SPEEDUP_GOAL}, ratio "
            f"{rate / SPEEDUP_GOAL:.2f}); overhead {extra['overhead']:.1%} (goal < "
            f"{OVERHEAD_GOAL:.0%}, ratio {extra['overhead'] / OVERHEAD_GOAL:.2f})"
        )
    print(json.dumps(report))


if __name__ == "__main__":
    main()
