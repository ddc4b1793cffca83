"""Air-launch optimisation: payload against the published figure, and solve time.

One full launch optimisation (genetic search, SLSQP, trust-constr) of the default
launcher to a 200 km circular orbit at 28.5 deg, timed in this process, printed
next to the published Pegasus XL figures of that class (from the launcher's
``published_performance``). Goals: payload within 20 % of the published
~450 kg; one optimisation under 60 s.

Run: ``python benchmarks/launch.py [--config FILE] [--json]``: a table, then one JSON
object with the figures, the goals and the ratios as the last line (``--json``: only
that). ``--config``: another scenario's launch settings (default the shipped one), e.g. a
smaller search.
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

import yaml
from goals import goal

from ovtraj.config import scenario_from_dict
from ovtraj.launch import launch_input, solve_launch

ROOT = Path(__file__).resolve().parents[1]
ALTITUDE_KM = 200.0
INCLINATION_DEG = 28.5
PAYLOAD_GOAL = goal("launch", "payload_fraction")  # accuracy: of the published figure
TIME_GOAL_S = goal("launch", "time_s")  # speed: one optimisation under it


def benchmark_scenario(config: Path = ROOT / "configs" / "scenario.yaml") -> dict:
    data = yaml.safe_load(config.read_text(encoding="utf-8"))
    data = copy.deepcopy(data)
    data["name"] = "benchmark-200km-28.5deg"
    data["target"]["orbit"]["inclination_deg"] = INCLINATION_DEG
    data["launch"]["target_altitude_km"] = ALTITUDE_KM
    return data


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "scenario.yaml")
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    args = parser.parse_args()
    say = (lambda *_: None) if args.json else print
    scenario = scenario_from_dict(benchmark_scenario(args.config), "benchmark")
    inp = launch_input(scenario)
    start = time.perf_counter()
    result = solve_launch(inp)
    elapsed = time.perf_counter() - start
    say(f"launch to {ALTITUDE_KM:g} km, {INCLINATION_DEG:g} deg ({inp.launcher.name})")
    say(f"  feasible: {result.feasible} {result.reason or ''}")
    say(f"  trajectories integrated: {result.trajectories}")
    say(
        f"  wall time: {elapsed:.1f} s "
        f"(goal < {TIME_GOAL_S:g} s, ratio {elapsed / TIME_GOAL_S:.2f})"
    )
    for phase in result.phases:
        say(
            f"    {phase.name:12s} payload {phase.payload_kg:8.2f} kg  violation "
            f"{phase.max_violation:9.3g}  {phase.iterations:3d} it  {phase.trajectories:5d} traj"
            f"  {phase.wall_time_s:6.1f} s"
        )
    say(f"  payload: {result.payload_kg:.1f} kg")
    published = []
    for ref in inp.launcher.published_performance:
        if ref.altitude_km == ALTITUDE_KM and ref.inclination_deg == INCLINATION_DEG:
            ratio = result.payload_kg / ref.payload_kg
            verdict = "within" if abs(ratio - 1) <= PAYLOAD_GOAL else "outside"
            say(
                f"  published {ref.payload_kg:.0f} kg ({ref.source}): ratio {ratio:.3f}, "
                f"{verdict} {100 * PAYLOAD_GOAL:.0f} %"
            )
            published.append(
                {
                    "payload_kg": ref.payload_kg,
                    "source": ref.source,
                    "ratio": round(ratio, 4),
                    "within": verdict == "within",
                }
            )
    figures = {
        "altitude_km": ALTITUDE_KM,
        "inclination_deg": INCLINATION_DEG,
        "feasible": bool(result.feasible),
        "trajectories": int(result.trajectories),
        "wall_s": round(elapsed, 3),
        "payload_kg": round(float(result.payload_kg), 3),
        "phases": [
            {
                "name": phase.name,
                "payload_kg": round(float(phase.payload_kg), 3),
                "iterations": int(phase.iterations),
                "trajectories": int(phase.trajectories),
                "wall_s": round(float(phase.wall_time_s), 3),
            }
            for phase in result.phases
        ],
        "published": published,
        "goals": {"time_s_max": TIME_GOAL_S, "payload_fraction_max": PAYLOAD_GOAL},
        "time_ratio": round(elapsed / TIME_GOAL_S, 3),
        "met": {
            "time": elapsed <= TIME_GOAL_S,
            "payload": bool(published) and all(p["within"] for p in published),
        },
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
