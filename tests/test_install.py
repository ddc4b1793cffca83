"""The wheel's contents and a ``--no-deps`` install of it, used from elsewhere.

The wheel is built from a copy of the working tree, installed without its
dependencies into a new virtual environment that sees this one's packages (a path
file), and its ``ovtraj`` command runs from an unrelated folder with an empty home:
the shipped configs and reference launch fit come from the package, the results go
to the workspace, and nothing is written inside the installed package.

It does not check the dependencies: the venv borrows this one's packages, the dev extra
included, so a runtime dependency missing from pyproject.toml goes unseen here (pyerfa
once did). tests/test_user_install.py installs as README command 1 does, every
dependency resolved by pip, and runs each command of the README's "Use" section.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from tests.conftest import REPO

# Left out of the fast tier (-m "not slow"): it builds the wheel and installs it into a new venv.
pytestmark = pytest.mark.slow


def _tracked_files() -> list[str]:
    done = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    )
    return [line for line in done.stdout.splitlines() if (REPO / line).is_file()]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("install")
    source = tmp / "source"
    for name in _tracked_files():
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / name, source / name)
    wheels = tmp / "wheels"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(source)],
        check=True,
        capture_output=True,
        timeout=600,
    )
    (wheel,) = wheels.glob("ovtraj-*.whl")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    python = venv / "bin" / "python"
    site = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    # The dependencies: this environment's packages, after the new venv's own.
    (Path(site) / "dependencies.pth").write_text(sysconfig.get_path("purelib") + "\n")
    subprocess.run(
        [python, "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    elsewhere, home = tmp / "elsewhere", tmp / "home"
    elsewhere.mkdir()
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("OVTRAJ_")}
    env |= {"HOME": str(home), "XDG_DATA_HOME": str(home / "share")}
    package = Path(site) / "ovtraj"
    before = sorted(p for p in package.rglob("*") if "__pycache__" not in p.parts)
    return {
        "venv": venv,
        "wheel": wheel,
        "package": package,
        "before": before,
        "cwd": elsewhere,
        "home": home,
        "env": env,
    }


def _run(installed, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(installed["venv"] / "bin" / "ovtraj"), *args],
        cwd=installed["cwd"],
        env=installed["env"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )


def test_the_wheel_ships_the_configs_and_reference_data_and_no_generic_package(installed):
    import zipfile

    names = zipfile.ZipFile(installed["wheel"]).namelist()
    tops = {n.split("/")[0] for n in names}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"ovtraj"}
    shipped = {str(p.relative_to(REPO / "configs")) for p in (REPO / "configs").rglob("*.yaml")}
    assert shipped == {n.removeprefix("ovtraj/configs/") for n in names if "/configs/" in n}
    reference = {n for n in names if n.startswith("ovtraj/reference/launch_fit/")}
    assert len(reference) == 3  # coefficients, grid, meta
    python = installed["venv"] / "bin" / "python"
    for module in ("tasks", "flows"):
        done = subprocess.run(
            [python, "-c", f"import {module}"],
            cwd=installed["cwd"],
            env=installed["env"],
            capture_output=True,
            text=True,
            check=False,
        )
        assert done.returncode == 1 and "ModuleNotFoundError" in done.stderr, module


def test_the_installed_command_runs_from_any_folder_into_the_workspace(installed):
    where = _run(installed, "paths", "--json")
    assert where.returncode == 0, where.stderr
    paths = json.loads(where.stdout)
    assert paths["source_checkout"] is False
    assert Path(paths["configs"]) == installed["package"] / "configs"
    workspace = installed["home"] / "share" / "ovtraj"
    assert Path(paths["workspace"]) == workspace
    # The shipped defaults run with no flag and no file of the user's.
    rendezvous = _run(installed, "rendezvous", "--json")
    assert rendezvous.returncode == 0, rendezvous.stderr
    assert json.loads(rendezvous.stdout)["feasible"] is True
    done = _run(installed, "run", "--samples", "2")
    assert done.returncode == 0, done.stderr
    (run_dir,) = (workspace / "runs").iterdir()
    assert f"stored in {run_dir}" in done.stdout
    assert _run(installed, "verify", run_dir.name).returncode == 0
    # Every runner is the package's own: a local Dask cluster of the installed package.
    parallel = _run(installed, "run", "--samples", "4", "--runner", "dask")
    assert parallel.returncode == 0, parallel.stderr
    (stored,) = [line for line in parallel.stdout.splitlines() if line.startswith("stored in ")]
    child = Path(stored.removeprefix("stored in "))
    assert child.parent == workspace / "runs" and child != run_dir
    shown = json.loads(_run(installed, "show", child.name).stdout)["manifest"]
    assert shown["status"] == "complete" and shown["evaluated"] == 4
    # OVTRAJ_HOME moves the workspace.
    moved = subprocess.run(
        [str(installed["venv"] / "bin" / "ovtraj"), "paths", "--json"],
        cwd=installed["cwd"],
        env=installed["env"] | {"OVTRAJ_HOME": str(installed["home"] / "elsewhere")},
        capture_output=True,
        text=True,
        check=True,
    )
    assert json.loads(moved.stdout)["run_store"] == str(installed["home"] / "elsewhere" / "runs")
    # A relative store in a scenario is relative to the scenario file's folder.
    scenario = installed["cwd"] / "mine" / "scenario.yaml"
    scenario.parent.mkdir()
    text = (installed["package"] / "configs" / "scenario.yaml").read_text(encoding="utf-8")
    scenario.write_text(text.replace("    store: null", "    store: my-runs"), encoding="utf-8")
    done = _run(installed, "run", str(scenario), "--samples", "2")
    assert done.returncode == 0, done.stderr
    assert len(list((scenario.parent / "my-runs").iterdir())) == 1
    # Nothing written inside the installed package.
    after = sorted(p for p in installed["package"].rglob("*") if "__pycache__" not in p.parts)
    assert after == installed["before"]


def test_a_crash_is_one_line_and_exit_2_not_the_infeasible_code(installed):
    done = _run(installed, "rendezvous", "no-such-file.yaml")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "no-such-file.yaml" in done.stderr


def test_the_installed_command_exports_and_flies_a_plan_with_the_shipped_settings(
    installed, tmp_path
):
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.mission.chain import MissionContext, MissionDesign
    from ovtraj.mission.plan_build import build_plan
    from ovtraj.mission.plan_store import write_plan
    from ovtraj.paths import config_path
    from ovtraj.target_sources import load_scenario

    scenario = load_scenario(config_path("scenario.yaml"))
    context = MissionContext(scenario, find_launch_fit(scenario))
    plan = build_plan(
        context, MissionDesign(285.06, 326.96, 0.79), source={}, launch_cache=tmp_path
    )
    plan_file, _ = write_plan(plan, installed["cwd"], "chosen")
    done = _run(installed, "export", plan_file.name, "--format", "opm", "--out", "chosen.opm")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"opm: {installed['cwd'] / 'chosen.opm'}"
    flown = _run(installed, "fly", plan_file.name, "--monte-carlo", "1", "--json")
    assert flown.returncode == 0, flown.stderr
    report = json.loads(flown.stdout)
    assert report["start"] == "drop" and report["monte_carlo"]["runs"] == 1
    missing = _run(
        installed, "fly", plan_file.name, "--monte-carlo", "1", "--dispersions", "no.yaml"
    )
    assert missing.returncode == 2 and "Traceback" not in missing.stderr
    assert len(missing.stderr.strip().splitlines()) == 1 and "no.yaml" in missing.stderr
