"""Run store: bytes per sample, and the cost of checked reads, side by side in one process.

The default scenario's DoE is evaluated once (``--samples``, default 16); the same
records are then written

- by the run store (format 2: declared schemas, zstd, trajectories stored at
  ``mission.store``'s steps, the rendezvous tables without the target's states), and
- as format 1 stored them (every trajectory row the stages produce, every column,
  pyarrow's default snappy encoding),

and the run is read back through the store's checked readers (size, SHA-256 and
schema of every file) and, for comparison, by ``pyarrow.dataset`` with no check.

Goal: at most 100 kB per sample on the default settings.

Run: ``python benchmarks/store.py [--samples N] [--json]``; the last line is one JSON
object with the figures, the goal and the ratios.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds
import pyarrow.parquet as pq
from goals import goal

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import STAGES, MissionContext
from ovtraj.runs import RunStore, execute, latin_hypercube
from ovtraj.runs.schemas import DATASETS
from ovtraj.target_sources import load_scenario

ROOT = Path(__file__).resolve().parents[1]
GOAL_BYTES_PER_SAMPLE = goal("store", "bytes_per_sample")  # the size goal, default settings
PROJECTED_SAMPLES = 10_000
REPEATS = 5


def _size(directory: Path) -> int:
    return sum(p.stat().st_size for p in directory.rglob("*") if p.is_file())


def _format_1(directory: Path, records: list, ids: list[int], batch_size: int) -> None:
    """The records as store format 1 wrote them (for the comparison only)."""
    for start in range(0, len(records), batch_size):
        part = f"part-{start // batch_size:05d}.parquet"
        pairs = list(
            zip(ids[start : start + batch_size], records[start : start + batch_size], strict=True)
        )
        for stage in STAGES:
            rows = [{"sample_id": s, **r.stages[stage]} for s, r in pairs if stage in r.stages]
            if rows:
                (directory / "stages" / stage).mkdir(parents=True, exist_ok=True)
                pq.write_table(pa.Table.from_pylist(rows), directory / "stages" / stage / part)
            tables = [
                r.trajectories[stage].assign(sample_id=s)
                for s, r in pairs
                if stage in r.trajectories
            ]
            tables = [t for t in tables if len(t)]
            if tables:
                (directory / "trajectories" / stage).mkdir(parents=True, exist_ok=True)
                frame = pd.concat(tables, ignore_index=True)
                frame.to_parquet(directory / "trajectories" / stage / part, index=False)
        (directory / "totals").mkdir(parents=True, exist_ok=True)
        totals = [{"sample_id": s, **r.totals(), "wall_time_s": r.wall_time_s} for s, r in pairs]
        pq.write_table(pa.Table.from_pylist(totals), directory / "totals" / part)


def _median(run: object) -> float:
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--json", action="store_true", help="print only the JSON line")
    args = parser.parse_args()
    scenario = load_scenario(ROOT / "configs" / "scenario.yaml")
    settings = scenario.mission.doe
    samples = latin_hypercube(scenario.mission.design_bounds, args.samples, settings.seed)
    start = time.perf_counter()
    records = execute.evaluate_batch(MissionContext(scenario, find_launch_fit(scenario)), samples)
    evaluation_s = time.perf_counter() - start
    ids = [int(i) for i in samples["sample_id"]]
    with tempfile.TemporaryDirectory() as tmp:
        store = RunStore(Path(tmp) / "runs")
        run = store.create(resolved=scenario.resolved(), samples=samples, seed=0, code="bench")
        steps = execute.trajectory_steps(scenario)
        start = time.perf_counter()
        for k, batch in run.batches(settings.batch_size):
            chosen = [int(i) for i in batch["sample_id"]]
            with run.claim(k):
                run.write_batch(
                    k, [records[ids.index(i)] for i in chosen], chosen, trajectory_steps=steps
                )
        write_s = time.perf_counter() - start
        execute.finish(run)
        old = Path(tmp) / "format-1"
        _format_1(old, records, ids, settings.batch_size)
        new_bytes, old_bytes = _size(run.directory), _size(old)
        trajectory_bytes = _size(run.directory / "trajectories")
        names = [n for n in DATASETS if n != "samples"]
        checked_s = _median(lambda: [run._dataset(n) for n in names])
        unchecked_s = _median(
            lambda: [ds.dataset(run.directory / n).to_table().to_pandas() for n in names]
        )
        verify_s = _median(run.verify)
        report = run.verify()
    per_sample = new_bytes / args.samples
    figures = {
        "samples": args.samples,
        "bytes_per_sample": round(per_sample),
        "bytes_per_sample_format_1": round(old_bytes / args.samples),
        "trajectory_share": round(trajectory_bytes / new_bytes, 3),
        "projected_gb_10000_samples": round(per_sample * PROJECTED_SAMPLES / 1e9, 3),
        "projected_gb_10000_samples_format_1": round(
            old_bytes / args.samples * PROJECTED_SAMPLES / 1e9, 3
        ),
        "write_s_per_sample": round(write_s / args.samples, 4),
        "evaluation_s_per_sample": round(evaluation_s / args.samples, 3),
        "checked_read_s": round(checked_s, 4),
        "unchecked_read_s": round(unchecked_s, 4),
        "verify_s": round(verify_s, 4),
        "verified_files": report.checked_files,
        "goal_bytes_per_sample": GOAL_BYTES_PER_SAMPLE,
        "ratio_bytes_to_goal": round(per_sample / GOAL_BYTES_PER_SAMPLE, 3),
        "ratio_format_2_to_1": round(new_bytes / old_bytes, 3),
        "ratio_checked_to_unchecked_read": round(checked_s / unchecked_s, 2),
        "goal_met": per_sample <= GOAL_BYTES_PER_SAMPLE,
    }
    if not args.json:
        print(f"run store, {args.samples} samples of {scenario.name} (medians of {REPEATS} reads)")
        print(f"  {'':34}{'format 2':>12}{'format 1':>12}")
        print(
            f"  {'bytes per sample':34}{figures['bytes_per_sample']:>12,}"
            f"{figures['bytes_per_sample_format_1']:>12,}   goal {GOAL_BYTES_PER_SAMPLE:,}"
        )
        print(
            f"  {'projected for 10,000 samples [GB]':34}{figures['projected_gb_10000_samples']:>12}"
            f"{figures['projected_gb_10000_samples_format_1']:>12}"
        )
        print(f"  trajectory share of the run        {figures['trajectory_share']:.1%}")
        print(
            f"  write per sample {1e3 * figures['write_s_per_sample']:.1f} ms (evaluation "
            f"{figures['evaluation_s_per_sample']:.2f} s)"
        )
        print(
            f"  read every dataset: checked {1e3 * checked_s:.1f} ms, unchecked "
            f"{1e3 * unchecked_s:.1f} ms (ratio {figures['ratio_checked_to_unchecked_read']}); "
            f"verify {1e3 * verify_s:.1f} ms for {report.checked_files} files"
        )
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
