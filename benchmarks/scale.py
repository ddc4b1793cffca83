"""Scale: a 10,000-sample DoE to a front, fits against samples, orchestration at 100,000
samples, a month's launch window, side by side in one run.

1. **Pipeline at scale.** A ``--samples`` DoE of the default scenario (a fresh store,
   nothing cached) on a pool of ``mission.doe.workers`` processes, the library path of
   ``ovtraj run --runner processes``; then what ``ovtraj optimize`` does: the surrogates
   (``fit_mission_surrogates`` with the fitting pool of ``ovtraj/pipeline/steps.py``) and
   NSGA-II on them. Measured: each step's wall time, the DoE's CPU-time per sample
   against the evaluation's own (the samples' wall times the batch markers record), the
   store's bytes per sample, and the peak resident memory of this process and its
   children together (sampled every 0.2 s).
2. **Fits against samples.** The surrogates fitted on the first n samples of that run
   for each ``--fit-sizes``; the exponent of fit time against n between the smallest and
   the largest. Side by side, the fit without the large-sample settings (``large_samples: null``:
   every candidate on every sample, CV on all of them, one process) at
   ``--baseline-size``.
3. **Orchestration.** ``--synthetic`` samples through ``run_doe`` on a real Dask
   cluster (``dask scheduler`` and two ``dask worker --nthreads 1`` processes started
   here, stopped by PID) with a synthetic evaluation: each batch job opens the run,
   claims its batch and stores records whose totals are a closed form of the design (no
   stage). Overhead per sample = (workers x wall - the jobs' summed time) / samples; also
   the whole wall per sample. Then ``ovtraj runs``, ``show`` and ``verify`` on that
   store (processes, timed) and the largest folder's entry count.
4. **Launch window.** ``ovtraj window configs/scenario.yaml --days N --runner processes``
   (N = ``--window-days``) in a fresh workspace (the shipped launch fits), then again
   unchanged.

Goals: DoE + fits + front at 10,000 samples <= 300 s wall on these 2 cores;
fits at 10,000 samples <= 60 s, growing about linearly from 1,000 (exponent <= ~1);
peak memory <= 4 GB; store <= 100 kB per sample; orchestration <= 1 ms per sample at
100,000 synthetic samples; a 30-day window <= 900 s cold, <= 60 s re-run.

Run: ``python benchmarks/scale.py [--samples 10000] [--fit-sizes 1000,2000,5000,10000]
[--baseline-size 1000] [--synthetic 100000] [--window-days 30] [--json]``; a part is
skipped with 0 (``--baseline-size 0``, ``--synthetic 0``, ``--window-days 0``). The last
line is one JSON object with the figures, the goals and the ratios (``--json``: only it).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from goals import goal  # noqa: E402

PIPELINE_GOAL_S = goal("scale", "pipeline_s")  # 10,000-sample DoE, surrogates and front
FIT_GOAL_S = goal("scale", "fit_s")  # the fits at 10,000 samples
EXPONENT_GOAL = goal("scale", "fit_exponent")  # fit time "at most ~linearly" in the samples
MEMORY_GOAL_BYTES = goal("scale", "memory_bytes")  # peak resident memory of the pipeline
STORE_GOAL_BYTES_PER_SAMPLE = goal("scale", "store_bytes_per_sample")  # run store, a sample
ORCHESTRATION_GOAL_MS = goal("scale", "orchestration_ms")  # per sample, 2-worker Dask cluster
WINDOW_COLD_GOAL_S = goal("scale", "window_cold_s")  # a 30-day scan from nothing cached
WINDOW_RERUN_GOAL_S = goal("scale", "window_rerun_s")  # the same scan again, unchanged
MEMORY_SAMPLING_S = 0.2


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--fit-sizes", default="1000,2000,5000,10000")
    parser.add_argument("--baseline-size", type=int, default=1000)
    parser.add_argument("--synthetic", type=int, default=100_000)
    parser.add_argument("--window-days", type=int, default=30)
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    return parser.parse_args()


class PeakMemory:
    """The largest summed resident memory of this process and its descendants, sampled."""

    def __init__(self) -> None:
        import psutil

        self.process = psutil.Process()
        self.peak = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self) -> None:
        import psutil

        while not self._stop.is_set():
            total = 0
            for process in [self.process, *self.process.children(recursive=True)]:
                try:
                    total += process.memory_info().rss
                except psutil.Error:
                    continue
            self.peak = max(self.peak, total)
            self._stop.wait(MEMORY_SAMPLING_S)

    def __enter__(self) -> PeakMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def _cpu_s() -> float:
    """CPU time of this process and its reaped children."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _size(directory: Path) -> int:
    return sum(p.stat().st_size for p in directory.rglob("*") if p.is_file())


def _scenario():
    from ovtraj.target_sources import load_scenario

    return load_scenario(ROOT / "configs" / "scenario.yaml")


def _first(data, n: int):
    """The training data of the first ``n`` samples (by sample id)."""
    order = slice(0, n)
    return dataclasses.replace(
        data,
        sample_ids=data.sample_ids[order],
        designs=data.designs[order],
        outputs={k: v[order] for k, v in data.outputs.items()},
        feasible=data.feasible[order],
        components={k: v[order] for k, v in data.components.items()},
    )


def _fit(scenario, data, *, pool: bool = True):
    """The surrogates of ``data`` as ``ovtraj optimize`` fits them; (set, seconds)."""
    from contextlib import nullcontext

    from ovtraj.mission.design_space import bounds_arrays
    from ovtraj.pipeline.mission_fit import fit_mission_surrogates
    from ovtraj.pipeline.steps import fitting_pool

    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    start = time.perf_counter()
    with fitting_pool(scenario, len(data)) if pool else nullcontext() as executor:
        fitted = fit_mission_surrogates(data, scenario, lower, upper, executor=executor)
    return fitted, time.perf_counter() - start


def _quality(fitted) -> dict:
    """Each regressed output's selected candidate and its CV RMSE."""
    validation = fitted.validation
    chosen = validation[validation["selected"].astype(bool) & (validation["kind"] == "regressor")]
    return {
        row.model: {"candidate": row.candidate, "cv_rmse": float(row.cv_rmse)}
        for row in chosen.itertuples(index=False)
    }


def _evaluated(scenario, store: Path, samples: int, **how):
    """A fresh DoE run of ``samples`` evaluated by ``run_doe`` (``how``: its runner and
    job options); (run, the batch jobs' summaries, wall seconds)."""
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.runs import RunStore, prepare_run, run_doe
    from ovtraj.version import code_version

    doe = scenario.mission.doe
    run = prepare_run(
        scenario, samples=samples, seed=doe.seed, code=code_version(), store=RunStore(store)
    )
    jobs: list[dict] = []
    start = time.perf_counter()
    run_doe(
        scenario,
        run,
        find_launch_fit(scenario),
        batch_size=run.batch_size(doe),
        on_batch=jobs.append,
        progress=lambda line: None,
        **how,
    )
    return run, jobs, time.perf_counter() - start


def pipeline_at_scale(samples: int, fit_sizes: list[int], baseline: int) -> dict:
    from ovtraj.optimize import Normalisation, surrogate_front
    from ovtraj.pipeline import training_data

    scenario = _scenario()
    doe = scenario.mission.doe
    out: dict = {"samples": samples, "workers": doe.workers}
    with tempfile.TemporaryDirectory(prefix="ovtraj-scale-") as tmp, PeakMemory() as memory:
        cpu = _cpu_s()
        run, jobs, out["doe_s"] = _evaluated(
            scenario, Path(tmp), samples, runner="processes", workers=doe.workers
        )
        out["doe_cpu_ms_per_sample"] = 1000 * (_cpu_s() - cpu) / samples
        evaluation = sum(
            float(t)
            for marker in run.markers().values()
            for t in marker["timing"]["sample_wall_time_s"].values()
        )
        out["evaluation_ms_per_sample"] = 1000 * evaluation / samples
        out["batches"] = len(jobs)
        out["batch_size"] = run.batch_size(doe)
        out["store_bytes_per_sample"] = _size(Path(run.directory)) / samples
        data = training_data(run)
        out["feasible"] = int(data.feasible.sum())
        fits = {}
        largest = None
        for n in sorted(set(fit_sizes)):
            fitted, seconds = _fit(scenario, _first(data, min(n, len(data))))
            fits[n] = {"fit_s": seconds, "models": _quality(fitted.main)}
            largest = fitted
        out["fits"] = fits
        settings = scenario.mission.optimize
        start = time.perf_counter()
        front = surrogate_front(largest, Normalisation.mission(settings), settings)
        out["front_s"] = time.perf_counter() - start
        out["front_points"] = len(front)
        out["hypervolume"] = front.hypervolume
        if baseline:
            before = scenario.model_copy(
                update={
                    "mission": scenario.mission.model_copy(
                        update={
                            "surrogate": scenario.mission.surrogate.model_copy(
                                update={"large_samples": None}
                            )
                        }
                    )
                }
            )
            subset = _first(data, baseline)
            fitted_before, before_s = _fit(before, subset, pool=False)
            fitted_now, now_s = _fit(scenario, subset)
            out["baseline"] = {
                "samples": baseline,
                "before_s": before_s,
                "now_s": now_s,
                "before_models": _quality(fitted_before.main),
                "now_models": _quality(fitted_now.main),
            }
    out["peak_memory_bytes"] = memory.peak
    sizes = sorted(fits)
    if len(sizes) >= 2:
        t0, t1 = fits[sizes[0]]["fit_s"], fits[sizes[-1]]["fit_s"]
        out["fit_exponent"] = math.log(t1 / t0) / math.log(sizes[-1] / sizes[0])
    out["pipeline_s"] = out["doe_s"] + fits[sizes[-1]]["fit_s"] + out["front_s"]
    return out


def _synthetic_batch_job(run_url, resolved, launch_fit, batch_index, batch, wait_s=None):
    """A batch job with the evaluation replaced by a closed form (store_batch_job's
    arguments and summary): the batch claimed and stored as a real one (totals, marker)."""
    import time as clock

    from ovtraj.mission import DESIGN_NAMES, MissionDesign, MissionRecord
    from ovtraj.runs import Run

    start = clock.perf_counter()
    run = Run.open(run_url)
    with run.claim(batch_index, wait_s=wait_s or 0.0) as claimed:
        if not claimed:
            return {"batch": batch_index, "stored": None, "wall_time_s": 0.0}
        records = []
        for row in batch:
            design = MissionDesign(**{name: float(row[name]) for name in DESIGN_NAMES})
            h = design.parking_altitude_km
            records.append(
                MissionRecord(
                    design=design,
                    feasible=True,
                    t_total_s=3600.0 * (60.0 + design.separation_delay_h),
                    dv_total_mps=150.0 + 0.1 * h,
                    m_load_kg=420.0 - 0.1 * h,
                )
            )
        ids = [int(row["sample_id"]) for row in batch]
        stored = run.write_batch(batch_index, records, ids, trajectory_steps={})
    return {
        "batch": batch_index,
        "stored": stored,
        "samples": len(batch),
        "feasible": len(batch),
        "wall_time_s": clock.perf_counter() - start,
    }


def _timed(command: list[str], env: dict) -> float:
    start = time.perf_counter()
    subprocess.run(command, env=env, check=True, capture_output=True, timeout=3600)
    return time.perf_counter() - start


def _largest_folder(directory: Path) -> int:
    return max((len(os.listdir(d)) for d, _, _ in os.walk(directory)), default=0)


def orchestration(samples: int) -> dict:
    from doe import Cluster

    from ovtraj.config.orchestration import load_orchestration

    scenario = _scenario()
    doe = scenario.mission.doe
    out: dict = {"samples": samples}
    with tempfile.TemporaryDirectory(prefix="ovtraj-orchestration-") as tmp:
        cluster = Cluster(Path(tmp), "scale", 2)
        try:
            cluster.wait()
            store = Path(tmp) / "store"
            run, jobs, wall = _evaluated(
                scenario,
                store,
                samples,
                runner="dask",
                dask_address=cluster.address,
                dask=load_orchestration().dask,
                job=_synthetic_batch_job,
            )
        finally:
            cluster.stop()
        busy = sum(job["wall_time_s"] for job in jobs)
        out.update(
            batches=len(jobs),
            batch_size=run.batch_size(doe),
            wall_s=wall,
            wall_ms_per_sample=1000 * wall / samples,
            overhead_ms_per_sample=1000 * max(2 * wall - busy, 0.0) / samples,
            largest_folder_entries=_largest_folder(store / run.id),
            stored_samples=len(run.totals()),
        )
        env = {**os.environ, "OVTRAJ_HOME": str(Path(tmp) / "home")}
        ovtraj = str(Path(sys.executable).with_name("ovtraj"))
        out["runs_s"] = _timed([ovtraj, "runs", "--store", str(store)], env)
        out["show_s"] = _timed([ovtraj, "show", run.id, "--store", str(store)], env)
        out["verify_s"] = _timed([ovtraj, "verify", run.id, "--store", str(store)], env)
    return out


def window(days: int) -> dict:
    with tempfile.TemporaryDirectory(prefix="ovtraj-window-") as tmp:
        env = {**os.environ, "OVTRAJ_HOME": tmp}
        ovtraj = str(Path(sys.executable).with_name("ovtraj"))
        scenario = str(ROOT / "configs" / "scenario.yaml")
        command = [ovtraj, "window", scenario, "--days", str(days), "--runner", "processes"]
        command.append("--allow-unconverged")  # timed: a day that did not converge counts too
        cold = _timed(command, env)
        rerun = _timed(command, env)
    return {"days": days, "cold_s": cold, "rerun_s": rerun}


def _figures(args: argparse.Namespace) -> dict:
    sizes = [int(n) for n in args.fit_sizes.split(",") if n]
    figures: dict = {"goals": {}, "ratios": {}}
    if args.samples:
        scale = pipeline_at_scale(args.samples, sizes, args.baseline_size)
        largest = scale["fits"][max(scale["fits"])]["fit_s"]
        figures["pipeline"] = scale
        figures["goals"].update(
            pipeline_s=PIPELINE_GOAL_S,
            fit_s=FIT_GOAL_S,
            fit_exponent=EXPONENT_GOAL,
            peak_memory_bytes=MEMORY_GOAL_BYTES,
            store_bytes_per_sample=STORE_GOAL_BYTES_PER_SAMPLE,
        )
        figures["ratios"].update(
            pipeline=scale["pipeline_s"] / PIPELINE_GOAL_S,
            fit=largest / FIT_GOAL_S,
            memory=scale["peak_memory_bytes"] / MEMORY_GOAL_BYTES,
            store=scale["store_bytes_per_sample"] / STORE_GOAL_BYTES_PER_SAMPLE,
        )
        if "baseline" in scale:
            base = scale["baseline"]
            figures["ratios"]["baseline_speedup"] = base["before_s"] / base["now_s"]
    if args.synthetic:
        orchestrated = orchestration(args.synthetic)
        figures["orchestration"] = orchestrated
        figures["goals"]["orchestration_ms_per_sample"] = ORCHESTRATION_GOAL_MS
        figures["ratios"]["orchestration"] = (
            orchestrated["wall_ms_per_sample"] / ORCHESTRATION_GOAL_MS
        )
    if args.window_days:
        scanned = window(args.window_days)
        figures["window"] = scanned
        figures["goals"].update(
            window_cold_s=WINDOW_COLD_GOAL_S, window_rerun_s=WINDOW_RERUN_GOAL_S
        )
        figures["ratios"].update(
            window_cold=scanned["cold_s"] / WINDOW_COLD_GOAL_S,
            window_rerun=scanned["rerun_s"] / WINDOW_RERUN_GOAL_S,
        )
    figures["met"] = {name: ratio <= 1.0 for name, ratio in figures["ratios"].items()}
    figures["met"].pop("baseline_speedup", None)  # a comparison, not a goal
    if "pipeline" in figures and "fit_exponent" in figures["pipeline"]:
        figures["met"]["fit_exponent"] = figures["pipeline"]["fit_exponent"] <= EXPONENT_GOAL
    return figures


def _print_table(figures: dict) -> None:
    rows: list[tuple[str, str, str]] = []
    scale = figures.get("pipeline")
    if scale:
        rows += [
            (f"DoE, {scale['samples']} samples", f"{scale['doe_s']:.1f} s", ""),
            ("  CPU per sample", f"{scale['doe_cpu_ms_per_sample']:.1f} ms", ""),
            ("  evaluation per sample", f"{scale['evaluation_ms_per_sample']:.1f} ms", ""),
            ("  batches x size", f"{scale['batches']} x {scale['batch_size']}", ""),
            (
                "  store per sample",
                f"{scale['store_bytes_per_sample'] / 1000:.1f} kB",
                f"<= {STORE_GOAL_BYTES_PER_SAMPLE / 1000:.0f} kB",
            ),
        ]
        for n, fit in sorted(scale["fits"].items()):
            picked = ", ".join(f"{m}: {q['candidate']}" for m, q in fit["models"].items())
            rows.append((f"fits, {n} samples", f"{fit['fit_s']:.1f} s", picked))
        if "fit_exponent" in scale:
            rows.append(("fit time ~ n^k", f"k = {scale['fit_exponent']:.2f}", "<= ~1"))
        rows += [
            ("NSGA-II front", f"{scale['front_s']:.1f} s", f"{scale['front_points']} points"),
            ("DoE + fits + front", f"{scale['pipeline_s']:.1f} s", f"<= {PIPELINE_GOAL_S:.0f} s"),
            ("peak memory", f"{scale['peak_memory_bytes'] / 1e9:.2f} GB", "<= 4 GB"),
        ]
        base = scale.get("baseline")
        if base:
            rows.append(
                (
                    f"fits at {base['samples']}: before / now",
                    f"{base['before_s']:.1f} / {base['now_s']:.1f} s",
                    "large_samples null / shipped",
                )
            )
    orchestrated = figures.get("orchestration")
    if orchestrated:
        rows += [
            (
                f"Dask, {orchestrated['samples']} synthetic samples",
                f"{orchestrated['wall_s']:.1f} s",
                f"{orchestrated['batches']} batches of {orchestrated['batch_size']}",
            ),
            (
                "  wall per sample",
                f"{orchestrated['wall_ms_per_sample']:.3f} ms",
                f"<= {ORCHESTRATION_GOAL_MS} ms",
            ),
            ("  overhead per sample", f"{orchestrated['overhead_ms_per_sample']:.3f} ms", ""),
            ("  largest folder", f"{orchestrated['largest_folder_entries']} entries", ""),
            (
                "  runs / show / verify",
                f"{orchestrated['runs_s']:.1f} / {orchestrated['show_s']:.1f} / "
                f"{orchestrated['verify_s']:.1f} s",
                "",
            ),
        ]
    scanned = figures.get("window")
    if scanned:
        rows += [
            (f"window, {scanned['days']} days, cold", f"{scanned['cold_s']:.0f} s", "<= 900 s"),
            ("window re-run", f"{scanned['rerun_s']:.1f} s", "<= 60 s"),
        ]
    width = max(len(r[0]) for r in rows)
    for name, value, note in rows:
        print(f"{name:<{width}}  {value:>18}  {note}")


def main() -> None:
    args = _arguments()
    figures = _figures(args)
    if not args.json:
        _print_table(figures)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
