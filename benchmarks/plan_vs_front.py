"""The front is flown as promised: plans against their front points, smoothness
and the rendezvous's cost, for the plane aimed at the rendezvous and the patent's plane.

Side by side in this process, on the default scenario (``configs/scenario.yaml``) and its
launch fit:

1. **front -> plan**: the default pipeline (the scenario's DoE size, surrogates, NSGA-II,
   verification and infill, serial) for each DoE seed; then the plan of *every* point of
   its verified front (:func:`ovtraj.mission.plan_build.plan_and_record`, the launch solved to
   the chain's insertion and cached, exactly what ``ovtraj plan RUN --pick i`` flies),
   its totals against the front's: the largest |dV_total|, |T_total| and |M_load|
   differences, and how many points :func:`~ovtraj.mission.plan_check.check_front_point` (the
   command's check, ``mission.plan.front_tolerance``) refuses.
2. **smoothness**: ``--designs`` designs of a seeded Latin hypercube over the design
   bounds, each evaluated again with H_P0 raised by 50 m: the fraction whose dV_total
   moves by less than 0.5 m/s.
3. **cost**: on the same designs, the rendezvous's dV over its coplanar two-body Hohmann
   cost between the mean radii (median, p90, max), the plane difference at the first
   burn, the median payload and T_total, and the feasible designs.

Each part runs for three chains: ``aimed`` (the shipped scenario: the launch target's
osculating circular orbit, the plane aimed at the rendezvous), ``patent plane`` (the same
insertion, the target's plane at insertion: ``mission.insertion.plane: launch``) and
``before`` (no ``mission.insertion``: the chain and the plan without plane management). The verified
fronts' best dV_total is compared between ``aimed`` and ``before`` at equal or better T_total
and M_load.

Goals: every front point planned within 1 m/s, 60 s and 0.1 kg on seeds 2026,
2027 and 2028 (``aimed``); >= 90 % of >= 30 designs move < 0.5 m/s per 50 m; the rendezvous
within 5 % of its Hohmann cost (median and p90).

Run: ``python benchmarks/plan_vs_front.py [--seeds 2026 2027 2028] [--designs 40]
[--chains aimed "patent plane" before] [--plans N] [--config FILE] [--json]``; ``--json``
prints only the JSON object, otherwise the tables and that object as the last line.
``--plans N`` plans the first N points of each front only, ``--config`` runs another
scenario (e.g. a smaller pipeline). Run stores and cached launches go to a temporary
folder, removed at the end. About 5-10 min here (the ``before`` plans solve the launch by
the stage's own optimisation, ~3 s each).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
from goals import goals

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

GOALS = goals("plan_vs_front")
CHAINS = ("aimed", "patent plane", "before")


def chain_scenario(scenario, chain: str):
    """The shipped scenario with the chain's ``mission.insertion``."""
    insertion = scenario.mission.insertion
    if chain == "aimed":
        return scenario
    if chain == "patent plane":
        insertion = insertion.model_copy(update={"plane": "launch"})
    else:
        insertion = None
    mission = scenario.mission.model_copy(update={"insertion": insertion})
    return scenario.model_copy(update={"mission": mission})


def front_vs_plans(scenario, fit, seed: int, folder: Path, plans: int | None = None) -> dict:
    """The default pipeline of ``seed``, then the plan of each verified front point (of
    the first ``plans`` only, if given)."""
    from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign
    from ovtraj.mission.plan import PlanError
    from ovtraj.mission.plan_build import plan_and_record
    from ovtraj.mission.plan_check import PlanMismatch, check_front_point
    from ovtraj.pipeline import PipelineSteps, run_pipeline
    from ovtraj.pipeline.planning import stored_stage_rows
    from ovtraj.runs import RunStore, prepare_run, run_doe

    store = RunStore(folder / "runs")
    settings = scenario.mission.doe

    def evaluate(run):
        return run_doe(scenario, run, fit, batch_size=settings.batch_size)

    doe = prepare_run(scenario, samples=settings.samples, seed=seed, code="benchmark", store=store)
    evaluate(doe)
    result = run_pipeline(
        scenario, doe, store=store, code="benchmark", steps=PipelineSteps(evaluate=evaluate)
    )
    context = MissionContext(scenario, fit)
    final = store.run(result.final_run)
    tolerance = scenario.mission.plan.front_tolerance
    points = []
    for row in result.front.to_dict("records")[:plans]:
        design = MissionDesign(**{name: float(row[name]) for name in DESIGN_NAMES})
        point = {"front_index": int(row["front_index"]), "sample_id": int(row["sample_id"])}
        try:
            _, record = plan_and_record(
                context, design, source={}, launch_cache=folder / "launch_solves"
            )
        except PlanError as err:
            points.append(point | {"error": str(err)})
            continue
        point |= {
            "front_dv_total_mps": float(row["dv_total_mps"]),
            "plan_dv_total_mps": record.dv_total_mps,
            "dv_total_mps": record.dv_total_mps - float(row["dv_total_mps"]),
            "t_total_s": record.t_total_s - float(row["t_total_s"]),
            "m_load_kg": record.m_load_kg - float(row["m_load_kg"]),
            "front_t_total_h": float(row["t_total_s"]) / 3600.0,
            "front_m_load_kg": float(row["m_load_kg"]),
        }
        if tolerance is not None:
            try:
                check_front_point(
                    record,
                    {k: float(row[k]) for k in ("dv_total_mps", "t_total_s", "m_load_kg")},
                    stored_stage_rows(final, point["sample_id"]),
                    tolerance,
                    f"front point {point['front_index']}",
                )
                point["refused"] = False
            except PlanMismatch:
                point["refused"] = True
        points.append(point)
    return {
        "seed": seed,
        "front_points": len(points),
        "hypervolume": result.summary["hypervolume"],
        "real_evaluations": sum(result.summary["real_evaluations"].values()),
        "points": points,
    }


def _largest(points: list[dict], key: str) -> float | None:
    values = [abs(p[key]) for p in points if key in p]
    return max(values) if values else None


def best_dv(points: list[dict], at_most_t_h: float | None = None, at_least_m: float | None = None):
    """The lowest front dV_total [m/s] among points with T <= ``at_most_t_h`` and M >=
    ``at_least_m`` (None when none qualifies)."""
    chosen = [
        p
        for p in points
        if "front_dv_total_mps" in p
        and (at_most_t_h is None or p["front_t_total_h"] <= at_most_t_h + 1e-9)
        and (at_least_m is None or p["front_m_load_kg"] >= at_least_m - 1e-9)
    ]
    return min(chosen, key=lambda p: p["front_dv_total_mps"]) if chosen else None


def design_space(scenario, fit, designs: int, seed: int) -> dict:
    """Smoothness and cost on a seeded hypercube of the design bounds."""
    from ovtraj.mission import MissionContext, MissionDesign, evaluate
    from ovtraj.mission.design_space import latin_hypercube

    context = MissionContext(scenario, fit)
    step_km = GOALS["smooth_step_m"] / 1e3
    ratios, planes, moves, payloads, times, dv_rendezvous = [], [], [], [], [], []
    feasible = 0
    table = latin_hypercube(scenario.mission.design_bounds, designs, seed)
    for row in table.itertuples(index=False):
        design = MissionDesign(
            row.parking_altitude_km, row.preparation_altitude_km, row.separation_delay_h
        )
        record = evaluate(context, design)
        raised = evaluate(
            context,
            MissionDesign(
                design.parking_altitude_km + step_km,
                design.preparation_altitude_km,
                design.separation_delay_h,
            ),
        )
        rendezvous = record.results.rendezvous
        if rendezvous is not None and rendezvous.feasible:
            hohmann = rendezvous.dv1_two_body_mps + rendezvous.dv2_two_body_mps
            ratios.append(rendezvous.dv_total_mps / hohmann)
            dv_rendezvous.append(rendezvous.dv_total_mps)
            planes.append(math.degrees(rendezvous.plane_difference_rad))
        if record.feasible:
            feasible += 1
            payloads.append(record.m_load_kg)
            times.append(record.t_total_s / 3600.0)
            if raised.feasible:
                moves.append(abs(raised.dv_total_mps - record.dv_total_mps))
    moves_a = np.array(moves)
    return {
        "designs": designs,
        "feasible": feasible,
        "smooth_pairs": len(moves),
        "smooth_fraction": float(np.mean(moves_a < GOALS["smooth_dv_mps"])) if moves else None,
        "smooth_move_median_mps": float(np.median(moves_a)) if moves else None,
        "smooth_move_p90_mps": float(np.percentile(moves_a, 90)) if moves else None,
        "rendezvous_designs": len(ratios),
        "rendezvous_dv_median_mps": statistics.median(dv_rendezvous) if ratios else None,
        "hohmann_ratio_median": statistics.median(ratios) if ratios else None,
        "hohmann_ratio_p90": float(np.percentile(ratios, 90)) if ratios else None,
        "hohmann_ratio_max": max(ratios) if ratios else None,
        "plane_difference_median_deg": statistics.median(planes) if planes else None,
        "plane_difference_max_deg": max(planes) if planes else None,
        "payload_median_kg": statistics.median(payloads) if payloads else None,
        "t_total_median_h": statistics.median(times) if times else None,
    }


def _f(value, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def main() -> None:
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.target_sources import load_scenario

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[2026, 2027, 2028])
    parser.add_argument("--designs", type=int, default=40)
    parser.add_argument("--design-seed", type=int, default=43)
    parser.add_argument("--chains", nargs="+", choices=CHAINS, default=list(CHAINS))
    parser.add_argument(
        "--plans",
        type=int,
        default=None,
        help="plan the first N points of each front only (default: every point)",
    )
    parser.add_argument(
        "--config",
        type=Path,
        default=ROOT / "configs" / "scenario.yaml",
        help="scenario (default: the shipped one); e.g. a smaller pipeline",
    )
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    args = parser.parse_args()
    say = (lambda *_: None) if args.json else print

    shipped = load_scenario(args.config)
    fit = find_launch_fit(shipped)
    figures: dict = {"chains": {}, "goals": GOALS}
    with tempfile.TemporaryDirectory(prefix="ovtraj-plan-vs-front-") as temporary:
        for chain in args.chains:
            scenario = chain_scenario(shipped, chain)
            seeds = [
                front_vs_plans(scenario, fit, seed, Path(temporary) / f"{chain}-{seed}", args.plans)
                for seed in args.seeds
            ]
            points = [p for s in seeds for p in s["points"]]
            figures["chains"][chain] = {
                "front_points": len(points),
                "plan_errors": sum("error" in p for p in points),
                "plans_refused": sum(bool(p.get("refused")) for p in points),
                "off_dv_1mps": sum(abs(p.get("dv_total_mps", 0.0)) > 1.0 for p in points),
                "max_dv_total_mps": _largest(points, "dv_total_mps"),
                "max_t_total_s": _largest(points, "t_total_s"),
                "max_m_load_kg": _largest(points, "m_load_kg"),
                "seeds": seeds,
                "design_space": design_space(scenario, fit, args.designs, args.design_seed),
            }
    chains = figures["chains"]
    say(
        f"front -> plan: the default pipeline (DoE seeds {', '.join(map(str, args.seeds))}), "
        "every verified front point planned"
    )
    say(
        f"  {'chain':<14}{'points':>7}{'refused':>8}{'>1 m/s':>8}{'max dV [m/s]':>14}"
        f"{'max T [s]':>11}{'max M [kg]':>11}"
    )
    for chain, c in chains.items():
        say(
            f"  {chain:<14}{c['front_points']:>7d}{c['plans_refused']:>8d}{c['off_dv_1mps']:>8d}"
            f"{_f(c['max_dv_total_mps'], 4):>14}{_f(c['max_t_total_s'], 3):>11}"
            f"{_f(c['max_m_load_kg'], 4):>11}"
        )
    for chain, c in chains.items():
        for seed in c["seeds"]:
            for p in seed["points"]:
                if "error" in p:
                    say(
                        f"  {chain}, seed {seed['seed']}, front point {p['front_index']}: "
                        f"{p['error']}"
                    )
    say(
        f"design space: {args.designs} designs (hypercube seed {args.design_seed}), H_P0 + "
        f"{GOALS['smooth_step_m']:g} m"
    )
    say(
        f"  {'chain':<14}{'feasible':>9}{'<0.5 m/s':>10}{'move p50':>10}{'rdv/Hoh p50':>12}"
        f"{'p90':>7}{'max':>7}{'plane [deg]':>12}{'dV_rdv p50':>11}{'M p50':>8}{'T p50 [h]':>10}"
    )
    for chain, c in chains.items():
        d = c["design_space"]
        say(
            f"  {chain:<14}{d['feasible']:>9d}{_f(d['smooth_fraction'], 2):>10}"
            f"{_f(d['smooth_move_median_mps'], 3):>10}{_f(d['hohmann_ratio_median']):>12}"
            f"{_f(d['hohmann_ratio_p90']):>7}{_f(d['hohmann_ratio_max']):>7}"
            f"{_f(d['plane_difference_median_deg'], 4):>12}"
            f"{_f(d['rendezvous_dv_median_mps'], 1):>11}"
            f"{_f(d['payload_median_kg'], 1):>8}{_f(d['t_total_median_h'], 1):>10}"
        )
    if "aimed" in chains and "before" in chains:
        comparison = []
        for new, old in zip(chains["aimed"]["seeds"], chains["before"]["seeds"], strict=True):
            before = best_dv(old["points"])
            after = (
                None
                if before is None
                else best_dv(new["points"], before["front_t_total_h"], before["front_m_load_kg"])
            )
            comparison.append(
                {
                    "seed": new["seed"],
                    "before_best_dv_total_mps": None
                    if before is None
                    else before["front_dv_total_mps"],
                    "before_t_total_h": None if before is None else before["front_t_total_h"],
                    "before_m_load_kg": None if before is None else before["front_m_load_kg"],
                    "aimed_best_dv_total_mps": None
                    if after is None
                    else after["front_dv_total_mps"],
                    "aimed_best_dv_overall_mps": (best_dv(new["points"]) or {}).get(
                        "front_dv_total_mps"
                    ),
                }
            )
        figures["best_dv"] = comparison
        say("verified fronts' best dV_total, aimed at equal or better T_total and M_load:")
        for c in comparison:
            say(
                f"  seed {c['seed']}: before {_f(c['before_best_dv_total_mps'], 1)} m/s (T "
                f"{_f(c['before_t_total_h'], 1)} h, M {_f(c['before_m_load_kg'], 1)} kg); aimed "
                f"{_f(c['aimed_best_dv_total_mps'], 1)} m/s (best overall "
                f"{_f(c['aimed_best_dv_overall_mps'], 1)} m/s)"
            )
    if "aimed" in chains:
        a, d = chains["aimed"], chains["aimed"]["design_space"]
        figures["met"] = {
            "plans": a["plan_errors"] == 0
            and (a["max_dv_total_mps"] or 0.0) <= GOALS["plan_dv_total_mps_max"]
            and (a["max_t_total_s"] or 0.0) <= GOALS["plan_t_total_s_max"]
            and (a["max_m_load_kg"] or 0.0) <= GOALS["plan_m_load_kg_max"],
            "smoothness": d["smooth_pairs"] >= 30
            and (d["smooth_fraction"] or 0.0) >= GOALS["smooth_fraction_min"],
            "cost": (d["hohmann_ratio_p90"] or math.inf) <= GOALS["rendezvous_hohmann_ratio_max"],
        }
        say(f"goals met: {figures['met']}")
    for c in chains.values():  # the last line: figures per seed, not per point
        c["seeds"] = [
            {k: v for k, v in s.items() if k != "points"}
            | {
                "max_dv_total_mps": _largest(s["points"], "dv_total_mps"),
                "max_t_total_s": _largest(s["points"], "t_total_s"),
                "max_m_load_kg": _largest(s["points"], "m_load_kg"),
            }
            for s in c["seeds"]
        ]
    print(json.dumps(figures, default=float))


if __name__ == "__main__":
    main()
