"""One whole-mission evaluation against the machine's speed reference (issue 20).

Side by side in this process:

1. one day of LEO J2 propagation (the default target's orbit) by scipy's DOP853 at
   rtol = atol = 1e-10, the reference figure of the developers' guide: a unit that moves
   with the machine's speed, so the ratio below does not;
2. the evaluation of the mission chain (``ovtraj.mission.evaluate``) on ``--designs``
   designs of a Latin hypercube over the design bounds (seeded), after ``--warm-up``
   evaluations that build the integrators and compile: the median wall time, and the
   median of each stage's own time (``MissionRecord.stage_time_s``) over the designs
   that reach it.

Goal (issue 20): ``ratio = median_eval_s / dop853_day_s <= 0.6``.

Run: ``python benchmarks/mission.py [--designs 20] [--repeats 3] [--json]``: ``--repeats``
evaluates the set that many times (each design's median is kept); ``--json`` prints only
the JSON object (otherwise the table, then that object as the last line).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from ovtraj.astro.propagation.reference import propagate_dop853
from ovtraj.config import load_scenario
from ovtraj.launch.fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES, STAGES, MissionContext, MissionDesign, evaluate
from ovtraj.paths import config_path
from ovtraj.runs import latin_hypercube

ROOT = Path(__file__).resolve().parents[1]
DAY_S = 86400.0
RATIO_GOAL = 0.6  # issue 20: one evaluation in at most 0.6 DOP853 days
DESIGN_SEED = 20  # the designs' hypercube (any fixed seed: the set must not move)


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--designs", type=int, default=20)
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
    scenario = load_scenario(config_path("scenario.yaml"))
    context = MissionContext(scenario, find_launch_fit(scenario))
    table = latin_hypercube(
        scenario.mission.design_bounds, args.warm_up + args.designs, seed=DESIGN_SEED
    )
    designs = [
        MissionDesign(**{name: float(getattr(row, name)) for name in DESIGN_NAMES})
        for row in table.itertuples(index=False)
    ]
    for design in designs[: args.warm_up]:
        evaluate(context, design)  # integrators built, numba compiled
    day = dop853_day_s(context, args.dop853_repeats)
    measured = evaluations(context, designs[args.warm_up :], args.repeats)
    day_after = dop853_day_s(context, args.dop853_repeats)  # the machine's drift
    day = statistics.median([day, day_after])
    median = statistics.median(measured["design_medians_s"])
    ratio = median / day
    stages = {stage: round(t, 5) for stage, t in measured["stage_medians_s"].items()}
    report = {
        "designs": args.designs,
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
        f"Mission evaluation: {args.designs} designs of the default scenario (hypercube seed "
        f"{DESIGN_SEED}, {measured['feasible']} feasible), {args.repeats} evaluations each, "
        f"after {args.warm_up} warm-up evaluations; DOP853 day: median of "
        f"{2 * args.dop853_repeats} runs before and after"
    )
    say(f"  {'':28}{'median [ms]':>12}{'/ DOP853 day':>14}{'designs':>9}")
    say(f"  {'DOP853, 1 day LEO J2, 1e-10':28}{day * 1e3:12.1f}{1.0:14.3f}")
    say(f"  {'whole evaluation':28}{median * 1e3:12.1f}{ratio:14.3f}{args.designs:9d}")
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
