"""The `ovtraj` command line, and the README/CI contract."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from io import StringIO
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from ovtraj.cli import app
from tests.conftest import DEFAULT_SCENARIO, DEORBIT_KEYS, REENTRY_KEYS, REPO, REQUIRED_KEYS

runner = CliRunner()


def test_rendezvous_json_is_exactly_one_object():
    result = runner.invoke(app, ["rendezvous", str(DEFAULT_SCENARIO), "--json"])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stdout.splitlines() if line.strip()]
    assert len(lines) == 1
    row = json.loads(lines[0])
    assert REQUIRED_KEYS <= row.keys()
    assert row["feasible"] is True and row["miss_distance_m"] <= 10.0


def test_rendezvous_summary():
    """Figures with their units and sensible digits: durations in hours (seconds when
    short), epochs as ISO 8601 UTC, no raw float and no None."""
    result = runner.invoke(app, ["rendezvous", str(DEFAULT_SCENARIO)])
    assert result.exit_code == 0
    out = result.stdout
    assert re.search(r"^  lead angle J2 +\d+\.\d{4} deg$", out, flags=re.M)
    assert re.search(r"^  miss distance +\S+ m$", out, flags=re.M)
    assert re.search(r"^  wait time +\d+\.\d{3} h$", out, flags=re.M)  # 10880 s
    assert re.search(r"^  transfer time +\d{4} s$", out, flags=re.M)  # 2430 s: short
    epoch = r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z"
    assert re.search(rf"^  burn 1 epoch +{epoch}$", out, flags=re.M)
    assert not re.search(r"\d\.\d{6,}", out) and "None" not in out


def test_bad_config_exits_2_with_the_field(tmp_path):
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["target"]["orbit"]["inclination_deg"] = 190.0
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["rendezvous", str(path), "--json"])
    assert result.exit_code == 2
    assert "target.orbit.inclination_deg = 190.0: out of range, allowed [0, 180] deg" in (
        result.stderr
    )
    assert result.stdout == ""


def test_infeasible_case_exits_1_with_reason(tmp_path):
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["parking_orbit"]["inclination_offset_deg"] = 3.0
    path = tmp_path / "tilted.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["rendezvous", str(path), "--json"])
    row = json.loads(result.stdout)
    assert result.exit_code == 1
    assert row["feasible"] is False and "plane difference" in row["reason"]
    summary = runner.invoke(app, ["rendezvous", str(path)])
    assert summary.exit_code == 1 and "plane difference" in summary.stdout


def test_version():
    from ovtraj import __version__
    from ovtraj.version import code_version

    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.stdout == f"ovtraj {code_version()}\n"
    assert code_version().startswith(__version__ + "+")  # what stored runs record


def test_ci_runs_the_readme_test_command():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    ci = (REPO / ".ci" / "run").read_text(encoding="utf-8")
    commands = re.findall(r"^python3 -m venv .*$", readme, flags=re.M)
    assert len(commands) == 2  # one runs the main job, one runs the tests
    test_command = next(c for c in commands if "pytest" in c)
    assert test_command in ci.splitlines()


def test_deorbit_json_carries_the_issue_keys_and_summary_prints():
    result = runner.invoke(app, ["deorbit", str(DEFAULT_SCENARIO), "--json"])
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)
    assert DEORBIT_KEYS <= row.keys()
    assert row["feasible"] is True
    deorbit = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))["deorbit"]
    assert (
        deorbit["entry"]["fpa_min_deg"]
        <= row["entry_fpa_deg"]
        <= deorbit["entry"]["fpa_max_deg"] + 1e-9
    )
    summary = runner.invoke(app, ["deorbit", str(DEFAULT_SCENARIO)])
    assert summary.exit_code == 0 and "burn epoch" in summary.stdout
    assert re.search(r"^  wait on the preparation orbit +\d+\.\d{3} h$", summary.stdout, re.M)


def test_deorbit_infeasible_exits_1_and_bad_config_exits_2(tmp_path):
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["deorbit"]["horizon_h"] = 2.0
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["deorbit", str(path), "--json"])
    assert result.exit_code == 1
    assert "within the 2 h horizon" in json.loads(result.stdout)["reason"]
    data["deorbit"]["entry"]["altitude_km"] = 400.0
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    bad = runner.invoke(app, ["deorbit", str(path)])
    assert bad.exit_code == 2 and "deorbit.entry.altitude_km" in bad.stderr


def test_reentry_json_carries_the_issue_keys_and_an_unreachable_site_exits_1(tmp_path):
    result = runner.invoke(app, ["reentry", str(DEFAULT_SCENARIO), "--json"])
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)
    assert REENTRY_KEYS <= row.keys()
    assert row["feasible"] is True and row["miss_distance_km"] <= 5.0
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["reentry"]["landing_site"].update({"latitude_deg": -10.0, "longitude_deg": 100.0})
    path = tmp_path / "far.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    far = runner.invoke(app, ["reentry", str(path)])
    assert far.exit_code == 1 and "outside the footprint" in far.stdout


OPTIMAL_ENTRY_CASE = REPO / "configs" / "cases" / "suborbital_return.yaml"


def test_optimal_entry_json_has_the_issue_keys_and_writes_the_histories(tmp_path):
    result = runner.invoke(
        app, ["optimal-entry", str(OPTIMAL_ENTRY_CASE), "--json", "--out", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)
    from tests.test_pseudospectral import RESULT_KEYS

    assert RESULT_KEYS - {"reason"} <= row.keys()
    assert row["converged"] is True
    # The terminal conditions of the case hold at the optimum.
    assert abs(row["final_altitude_km"] - 30.0) < 1e-3
    assert abs(row["final_speed_mps"] - 860.0) < 0.1
    # Absolute paths, in one subfolder named by the histories' content (a stored file is
    # never overwritten): the same result again writes nothing new.
    paths = {name: Path(row[name]) for name in ("states", "controls", "plot")}
    for path in paths.values():
        assert path.is_absolute() and path.is_file() and path.parent.parent == tmp_path
    again = runner.invoke(
        app, ["optimal-entry", str(OPTIMAL_ENTRY_CASE), "--json", "--out", str(tmp_path)]
    )
    assert again.exit_code == 0, again.output
    assert {name: Path(json.loads(again.stdout)[name]) for name in paths} == paths
    assert len(list(tmp_path.iterdir())) == 1


def test_optimal_entry_unposable_config_exits_2_with_the_field(tmp_path):
    data = yaml.safe_load(OPTIMAL_ENTRY_CASE.read_text(encoding="utf-8"))
    data["terminal"]["speed_mps"] = {"value": 3000.0}  # terminal energy above the initial
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["optimal-entry", str(path), "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "energy" in result.output


def test_optimal_entry_that_does_not_fly_exits_1_with_the_reason(tmp_path):
    """IPOPT succeeds on a coarse mesh whose controls do not fly to its end point: exit 1,
    the reason printed (IPOPT's false convergence), the histories still written."""
    case = REPO / "configs" / "cases" / "shuttle_crossrange_heating.yaml"
    data = yaml.safe_load(case.read_text(encoding="utf-8"))
    data["transcription"]["max_refinements"] = 0
    path = tmp_path / "coarse.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(
        app, ["optimal-entry", str(path), "--independent", "time", "--out", str(tmp_path)]
    )
    assert result.exit_code == 1, result.output
    assert "converged" in result.stdout and "False" in result.stdout
    assert "no re-flight of the interpolated controls meets the tolerance" in result.stdout
    assert "Solve_Succeeded" in result.stdout
    assert "Traceback" not in result.output


MANEUVER_CASE = REPO / "configs" / "cases" / "upper_stage_rendezvous.yaml"


def test_maneuver_json_has_the_issue_keys():
    result = runner.invoke(app, ["maneuver", str(MANEUVER_CASE), "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    from tests.test_maneuver import BURN_KEYS, MANEUVER_KEYS

    assert MANEUVER_KEYS <= doc.keys()
    assert all(BURN_KEYS <= burn.keys() for burn in doc["burns"])
    assert doc["converged"] is True
    assert doc["total_dv_mps"] <= doc["dv_budget_mps"]
    assert doc["final_position_error_m"] < 10.0


def test_maneuver_bad_config_exits_2_naming_the_field(tmp_path):
    data = yaml.safe_load(MANEUVER_CASE.read_text(encoding="utf-8"))
    data["stage"]["initial_mass_kg"] = -1.0
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["maneuver", str(path)])
    assert result.exit_code == 2
    assert "stage.initial_mass_kg = -1.0: out of range" in result.output


DEORBIT_BURN_CASE = REPO / "configs" / "cases" / "shuttle_deorbit.yaml"


def test_deorbit_burn_json_has_the_issue_keys_and_the_dispersion_statistics(tmp_path, monkeypatch):
    """The Monte Carlo is stored in the workspace's runs/ (the case names no store)."""
    monkeypatch.setenv("OVTRAJ_HOME", str(tmp_path))
    result = runner.invoke(
        app,
        ["deorbit-burn", str(DEORBIT_BURN_CASE), "--json", "--monte-carlo", "3", "--strategy", "1"],
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    from ovtraj.studies.deorbit_burn.report import REPORT_KEYS

    assert set(REPORT_KEYS) - {"reason"} <= doc.keys()
    assert doc["converged"] is True and doc["strategy"] == 1
    assert abs(doc["entry_u_error_deg"]) <= 0.01  # the configured convergence tolerance
    (stats,) = doc["monte_carlo"]
    assert stats["strategy"] == 1 and stats["runs"] == 3
    run = doc["monte_carlo_run"]
    assert run["directory"] == str(tmp_path.resolve() / "runs" / run["run_id"])
    assert run["strategies"] == [1] and run["simulated_runs"] == 3
    assert all(Path(p).is_file() and Path(p).is_absolute() for p in run["plots"])


def test_deorbit_burn_bad_value_exits_2_naming_the_field(tmp_path):
    data = yaml.safe_load(DEORBIT_BURN_CASE.read_text(encoding="utf-8"))
    data["guidance"]["gain_ku"] = 1.5
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = runner.invoke(app, ["deorbit-burn", str(path)])
    assert result.exit_code == 2
    assert "guidance.gain_ku = 1.5: out of range" in result.output


# --------------------------------------------------------------------------- #
# usability: refused values, help with units and defaults, --json, -q, progress bars
# --------------------------------------------------------------------------- #
OVTRAJ = Path(sys.executable).with_name("ovtraj")


@pytest.mark.parametrize("command", ["run", "pipeline"])
def test_samples_0_is_refused_in_one_line_naming_the_option(tmp_path, command):
    """Not silently replaced by the config's 8: exit 2, one line naming --samples."""
    done = subprocess.run(
        [OVTRAJ, command, "--samples", "0", "--store", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2 and done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert line.startswith(f"ovtraj {command}: ") and "'--samples'" in line
    assert not list(tmp_path.iterdir())


def _help(*command: str) -> str:
    result = runner.invoke(app, [*command, "--help"])
    assert result.exit_code == 0, result.output
    assert "<bool>" not in result.stdout  # flags show no type
    return " ".join(re.sub(r"[│╭╮╰╯─]", " ", result.stdout).split())


def test_help_shows_units_and_defaults():
    shown = _help("plan")
    assert "dV_total <= this [m/s] (default: no limit)" in shown
    assert "M_load >= this [kg]" in shown and "T_total <= this [h]" in shown
    shown = _help("launch")
    assert "target altitude [km], 150-2000 (default: the config's" in shown
    shown = _help("run")
    assert "--samples <int range> [1<=x<=100000] DoE samples (default:" in shown
    assert "--json print one JSON object on stdout" in shown
    assert "[default: 0]" in _help("fly")
    shown = _help()
    assert "--quiet -q" in shown and "--verbose -v" in shown


def _one_object(stdout: str) -> dict:
    (line,) = stdout.splitlines()
    return json.loads(line)


def test_json_alone_on_stdout_progress_on_stderr_and_quiet(tmp_path, monkeypatch):
    """``--json``: one object on stdout, the batch lines logged on stderr; ``-q``: nothing
    on stderr; then the human summary: hours, ISO UTC, units."""
    from ovtraj.config.orchestration import RESULTS_ENV

    # The task results' default folder (the session's Prefect server names its own).
    monkeypatch.delenv(RESULTS_ENV, raising=False)
    store = str(tmp_path / "runs")
    args = ["run", str(DEFAULT_SCENARIO), "--samples", "1", "--store", store, "--json"]
    done = runner.invoke(app, args)  # the config's seed: a feasible sample
    assert done.exit_code == 0, done.output
    row = _one_object(done.stdout)
    assert row["samples"] == 1 and row["status"] == "complete"
    assert re.search(r"^batch 1/1: 1 samples, 1 feasible", done.stderr, flags=re.M)
    quiet = runner.invoke(app, ["-q", *args, "--seed", "4"])
    assert quiet.exit_code == 0, quiet.output
    assert _one_object(quiet.stdout)["status"] == "complete" and quiet.stderr == ""
    rid = row["run_id"]
    for command in (["verify", rid, "--store", store], ["replay", rid, "--store", store]):
        result = runner.invoke(app, [*command, "--json"])
        assert result.exit_code == 0, result.output
        assert _one_object(result.stdout)["run_id"] == rid and result.stderr == ""
    paths = runner.invoke(app, ["paths", "--json"])
    assert paths.exit_code == 0
    named = _one_object(paths.stdout)
    assert {"run_store", "launch_fits", "optimal_entry", "prefect_results"} <= set(named)
    assert named["prefect_results"] == str(Path(named["workspace"]) / "prefect-results")
    again = runner.invoke(app, args[:-1])  # stored: nothing evaluated
    assert again.exit_code == 0, again.output
    assert re.search(r"^  min t total +\d+\.\d{3} h$", again.stdout, flags=re.M)
    assert re.search(r"^  created +\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$", again.stdout, re.M)
    assert re.search(r"^  min dv total +\d+(\.\d+)? m/s$", again.stdout, flags=re.M)
    assert "None" not in again.stdout


def test_progress_bar_only_on_a_terminal_and_never_quiet(monkeypatch):
    from rich.console import Console

    from ovtraj.cli import progress as cli_progress

    def shown(*, quiet: bool = False, enabled: bool = True, terminal: bool = True) -> str:
        out = StringIO()
        console = Console(file=out, force_terminal=terminal, width=100)
        monkeypatch.setattr(cli_progress, "console", console)
        cli_progress.configure_logging(quiet=quiet)
        with cli_progress.progress_bar("DoE samples", enabled=enabled) as update:
            update(0, 4, "batch 0/2")
            update(4, 4, "batch 2/2")
        return out.getvalue()

    try:
        assert "DoE samples: batch" in shown() and "ETA" in shown()
        assert shown(quiet=True) == ""
        assert shown(enabled=False) == ""  # --json
        assert shown(terminal=False) == ""  # a pipe: debug messages only
    finally:
        cli_progress.configure_logging()


@pytest.mark.parametrize(
    ("words", "cword", "expected"),
    [("ovtraj pip", 1, "pipeline"), ("ovtraj verify --rec", 2, "--recompute")],
)
def test_the_shell_completes_commands_and_options(words, cword, expected):
    """Bash's completion as `ovtraj --install-completion` installs it asks the command."""
    env = dict(os.environ, _OVTRAJ_COMPLETE="complete_bash", COMP_WORDS=words)
    env["COMP_CWORD"] = str(cword)
    done = subprocess.run(
        [str(Path(sys.executable).with_name("ovtraj"))],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0 and done.stdout.split() == [expected], done.stdout + done.stderr
