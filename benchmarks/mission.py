"""One whole-mission evaluation against the machine's speed reference.

Side by side in this process:

1. one day of LEO J2 propagation (the default target's orbit) by scipy's DOP853 at
   rtol = atol = 1e-10, the reference figure of the developers' guide: a unit that moves
   with the machine's speed, so the ratio below does not;
2. the evaluation of the mission chain (``ovtraj.mission.evaluate``) on the reference
   designs (``configs/mission_reference.yaml``: 20 of a seeded hypercube over the design
   bounds, the set whose results tests/test_mission_reference.py holds), after
   ``--warm-up`` evaluations that build the integrators and compile: the median wall
   time, and the
   median of each stage's own time (``MissionRecord.stage_time_s``) over the designs
   that reach it.

Goal: ``ratio = median_eval_s / dop853_day_s <= 0.6``.

Run: ``python benchmarks/mission.py [--repeats 3] [--json]``: ``--repeats`` evaluates the
set that many times (each design's median is kept), with DOP853 days timed between the
rounds; ``--json`` prints only the JSON object (otherwise the table, then that object as
the last line).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from goals import goal

from ovtraj.astro.propagation.reference import propagate_dop853
from ovtraj.mission import STAGES, MissionContext, MissionDesign, evaluate, reference

ROOT = Path(__file__).resolve().parents[1]
DAY_S = 86400.0
RATIO_GOAL = goal("mission", "ratio")  # the chain's speed goal: an evaluation in DOP853 days


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--warm-up", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dop853-repeats", type=int, default=5)
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    return parser.parse_args()


def dop853_day_s(context: MissionContext, repeats: int) -> float:
    """Median wall time of one day of LEO J2 by DOP853 at rtol = atol = 1e-10 [s], from
    the scenario's target state."""
    earth, state = context.scenario.earth, context.target0
    grav = {"mu": earth.mu, "radius": earth.radius, "j2": earth.j2}
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        propagate_dop853(state, 0.0, DAY_S, rtol=1e-10, atol=1e-10, **grav)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def evaluations(context: MissionContext, designs: list[MissionDesign], repeats: int) -> dict:
    """Each design's median wall time [s] and each stage's median times [s]."""
    per_design: list[list[float]] = [[] for _ in designs]
    per_stage: dict[str, list[float]] = {stage: [] for stage in STAGES}
    feasible = 0
    for repeat in range(repeats):
        for k, design in enumerate(designs):
            start = time.perf_counter()
            record = evaluate(context, design)
            per_design[k].append(time.perf_counter() - start)
            if repeat == 0:
                feasible += bool(record.totals()["feasible"])
            for stage, seconds in record.stage_time_s.items():
                per_stage[stage].append(seconds)
    return {
        "design_medians_s": [statistics.median(times) for times in per_design],
        "stage_medians_s": {
            stage: statistics.median(times) for stage, times in per_stage.items() if times
        },
        "stage_counts": {stage: len(times) // repeats for stage, times in per_stage.items()},
        "feasible": feasible,
    }


def main() -> None:
    args = _arguments()
    say = (lambda *_: None) if args.json else print
    settings = reference.load_settings()
    context = reference.context(settings)
    designs = reference.designs(context.scenario, settings)
    for design in designs[: args.warm_up]:
        evaluate(context, design)  # integrators built, numba compiled
    # The reference's timings interleaved with the evaluations: the VM's speed drifts.
    days: list[float] = []
    runs: list[dict] = []
    for _ in range(args.repeats):
        days.append(dop853_day_s(context, args.dop853_repeats))
        runs.append(evaluations(context, designs, 1))
    days.append(dop853_day_s(context, args.dop853_repeats))
    day = statistics.median(days)
    measured = {
        "design_medians_s": [
            statistics.median(run["design_medians_s"][k] for run in runs)
            for k in range(len(designs))
        ],
        "stage_medians_s": {
            stage: statistics.median(run["stage_medians_s"][stage] for run in runs)
            for stage in runs[0]["stage_medians_s"]
        },
        "stage_counts": runs[0]["stage_counts"],
        "feasible": runs[0]["feasible"],
    }
    median = statistics.median(measured["design_medians_s"])
    ratio = median / day
    stages = {stage: round(t, 5) for stage, t in measured["stage_medians_s"].items()}
    report = {
        "designs": len(designs),
        "repeats": args.repeats,
        "feasible_designs": measured["feasible"],
        "median_eval_s": round(median, 5),
        "dop853_day_s": round(day, 5),
        "ratio": round(ratio, 3),
        "ratio_goal": RATIO_GOAL,
        "goal_ratio": round(ratio / RATIO_GOAL, 3),
        "stages": stages,
        "stage_ratios": {stage: round(t / day, 3) for stage, t in stages.items()},
        "stage_counts": measured["stage_counts"],
    }
    say(
        f"Mission evaluation: the {len(designs)} reference designs of the default scenario "
        f"(configs/mission_reference.yaml, {measured['feasible']} feasible), {args.repeats} "
        f"evaluations each after {args.warm_up} warm-up evaluations; DOP853 day: median of "
        f"{len(days) * args.dop853_repeats} runs between the evaluation rounds"
    )
    say(f"  {'':28}{'median [ms]':>12}{'/ DOP853 day':>14}{'designs':>9}")
    say(f"  {'DOP853, 1 day LEO J2, 1e-10':28}{day * 1e3:12.1f}{1.0:14.3f}")
    say(f"  {'whole evaluation':28}{median * 1e3:12.1f}{ratio:14.3f}{len(designs):9d}")
    for stage, seconds in stages.items():
        say(
            f"  {'  ' + stage:28}{seconds * 1e3:12.1f}{seconds / day:14.3f}"
            f"{measured['stage_counts'][stage]:9d}"
        )
    say(
        f"  ratio {ratio:.3f} (goal <= {RATIO_GOAL}, {'met' if ratio <= RATIO_GOAL else 'NOT met'})"
    )
    print(json.dumps(report))


if __name__ == "__main__":
    main()
