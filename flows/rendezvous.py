"""Flow: the rendezvous stage on a scenario file (``flows/rendezvous.py:rendezvous_flow``)."""

from __future__ import annotations

from prefect import flow, get_run_logger, tags

from flows.common import (
    FLOW_TIMEOUTS,
    label_flow_run,
    prepared,
    prune_expired_results,
    run_name,
    run_tags,
)
from ovtraj.paths import scenario_file
from ovtraj.target_sources import load_scenario
from tasks.rendezvous import rendezvous_task


@flow(
    name="rendezvous",
    flow_run_name=run_name("rendezvous"),
    timeout_seconds=FLOW_TIMEOUTS.rendezvous_s,
    log_prints=False,
)
def rendezvous_flow(config: str | None = None) -> dict:
    """Load the scenario (default: the shipped one), solve the rendezvous (a cached task),
    log the key figures."""
    prune_expired_results()
    scenario = load_scenario(scenario_file(config))
    labels = run_tags("rendezvous", scenario.name)
    label_flow_run(f"rendezvous {scenario.name}", labels)
    with tags(*labels):
        row = prepared(rendezvous_task)(scenario.resolved())
    get_run_logger().info(
        "rendezvous %s: feasible=%s dv1=%s m/s dv2=%s m/s wait=%s s miss=%s m",
        scenario.name,
        row["feasible"],
        row["dv1_mps"],
        row["dv2_mps"],
        row["wait_time_s"],
        row["miss_distance_m"],
    )
    return row


if __name__ == "__main__":
    rendezvous_flow()
