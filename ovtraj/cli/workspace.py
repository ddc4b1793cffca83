"""The ``paths`` command: where ovtraj reads its shipped files and writes its results."""

from __future__ import annotations

from ovtraj import paths as where
from ovtraj.cli.common import JsonOpt, app, print_json, print_rows
from ovtraj.config.orchestration import load_orchestration
from ovtraj.store.paths import store_root


@app.command()
def paths(as_json: JsonOpt = False) -> None:
    """Where ovtraj reads its shipped files and writes its results (the workspace).

    Example: `ovtraj paths --json`"""
    found = {
        "configs": str(where.config_dir()),
        "reference": str(where.reference_dir()),
        "default_scenario": str(where.config_dir() / "scenario.yaml"),
        "workspace": str(where.workspace()),
        "run_store": str(store_root(None, None, None)),
        "launch_fits": str(where.workspace() / "launch_fit"),
        "optimal_entry": str(where.workspace() / "optimal_entry"),  # `optimal-entry`'s default
        "prefect_results": load_orchestration().results.location(),
        "source_checkout": where.source_checkout(),
    }
    if as_json:
        print_json(found)
    else:
        labels = {"workspace": "workspace (OVTRAJ_HOME)"}
        rows = [(labels.get(k, k.replace("_", " ")), v) for k, v in found.items()]
        print_rows("ovtraj paths", rows)
