"""The package as README command 1 installs it, and every command of the README's "Use"
section and of docs/commands.md run once by that install; the package as ``pip install .``
installs it, and the "Use" commands that need its package data.

tests/test_install.py installs the wheel without its dependencies into a venv that
borrows this one's packages, so it cannot see a dependency missing from pyproject.toml:
``ovtraj export`` failed on a user's install (``No module named 'erfa'``: pyerfa came only
with astropy, a dev extra). Here the files a checkout holds (tests/test_install.py's
``_tracked_files``) are copied to a temporary folder and installed as README command 1
does: ``python3 -m venv V && V/bin/pip install -e COPY`` (python3: the interpreter running
the tests), no dev extra, every dependency resolved by pip from the indexes its user's
configuration names (2 min on 2 quiet cores here, 4 beside other work; the venv, 1.8 GB,
is removed at the end by a process the session does not wait for). A first test
checks the same statically, in a second: every package the code imports is installed by
the runtime dependencies.

Each command of the "Use" section, read from README.md, then runs once in the README's
order with ``V/bin/ovtraj`` / ``V/bin/python -m flows.X``, from folders that are neither
the copy nor this checkout, with a home (``HOME``) and workspaces (``OVTRAJ_HOME``) in
temporary folders. It must exit 0, print no traceback, print exactly one JSON object with
``--json``, and every absolute path it prints (the files it wrote) must exist. Where the
run differs from the README's text, and why:

- placeholders: ``RUN_ID`` and ``PLAN.json`` are the DoE run and the plan of the README's
  main job (``ovtraj pipeline configs/scenario.yaml``, run first), ``PREVIOUS.json`` that
  plan again (the main job makes one: ``ovtraj diff`` of it with itself, empty),
  ``iss.tle`` the ISS TLE of tests/data/targets, ``HOST:8786`` a TLS Dask scheduler and
  worker of the installed venv on 127.0.0.1 (tests/test_dask_tls.py's certificates; the
  worker has the S3 credentials, as a cluster sharing the store must), ``s3://bucket/prefix``
  a bucket of a moto S3 server (tests/test_object_store.py); an optional ``[...]`` is left out;
- short settings (command 1's part takes 4.5 min on 2 quiet cores here, 2 of them the
  install; 12 min beside other work, load ~5): each folder's ``configs/`` is a copy of the
  shipped one with smaller budgets: the mission folder's scenario has
  tests/test_pipeline.py's (a 12-sample DoE, one infill round of 2 points, two regressors,
  3 folds, a smaller NSGA-II) and the shipped launch section, so the shipped launch fit
  serves it; the launch folder's, for ``launch``, ``launch-fit`` and ``flows.launch_fit``,
  has tests/test_caching.py's 5-point grid and small GA (seconds instead of 1-4 min); the
  deorbit Monte Carlo 4 runs, ``--monte-carlo 4`` instead of 100; a flow given no config
  reads the shipped scenario (as ``ovtraj`` does), so ``OVTRAJ_CONFIG_DIR`` names the
  folder's shortened copy for the flows;
- the flows are not installed (README, "Installing"): each folder links the copy's
  ``flows/`` and ``tasks/`` in, as a checkout holds them, and the flows run against the
  session's Prefect server (tests/conftest.py) in a workspace of their own, so that they
  evaluate their DoE and solve their fit rather than find the command line's;
- ``ovtraj run``: a workspace of its own too, where ``--runner processes`` evaluates its
  samples on the process pool (in the main job's workspace its run is the pipeline's DoE,
  already stored);
- one compiled-code cache (``XDG_CACHE_HOME``) for both installs, as a user's ``~/.cache``
  is across installs: heyoka keeps its compiled Taylor integrators there (~10 s in an empty
  one, paid by the editable part's first commands); the homes are otherwise empty and apart.
  numba caches its kernels beside their sources: each install compiles them once.

Then the same venv holds the package as ``pip install COPY`` installs it: the editable
install is uninstalled, its copy deleted, and a second copy installed by ``V/bin/pip install
--no-deps COPY`` (not editable; ~10 s, where a fresh venv resolves and installs the
dependencies in 80-100 s) and deleted. The dependencies are the ones pip resolved for
README command 1 from the same pyproject.toml, which ``pip install COPY`` finds installed
(``pip check``: every requirement of the installed package is met). Nothing can come from
a source tree: no ``__editable__`` path file or finder is left, no entry of the venv's
path lies outside the venv and the interpreter's library, and the configs and the
reference data are the ones inside the package (``ovtraj paths`` must say so). The wheel
fixture depends on the editable one and its tests come after the editable ones in the
module; a test of the editable install run after the switch fails, saying so. The "Use"
commands that differ between the two installs (``WHEEL_USE``: the shipped scenario, its
launcher, the reference launch fit, the export's settings and pyerfa) run as above, from a
folder whose ``configs/`` is a shortened copy of the installed ones (the main job's
scenario); a shipped config file is named by its installed path. Every module of the
package and every package the code imports must import. This part costs 1.4 min beside
other work (load ~5 on 2 cores; the module 13.5 min).
"""

from __future__ import annotations

import ast
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests import test_object_store
from tests.conftest import REPO, shorten_launch_fit
from tests.test_dask_tls import TlsCluster
from tests.test_install import _tracked_files

# Left out of the fast tier (-m "not slow"): it installs into a fresh venv with every dependency
# resolved by pip and runs every README command.
pytestmark = pytest.mark.slow

INSTALL_TIMEOUT_S = 900.0  # a fresh venv's `pip install -e`: 2-4 min here
COMMAND_TIMEOUT_S = 300.0  # the longest command with these settings: ~30 s (the first, compiling)
MONTE_CARLO_RUNS = "4"  # for `--monte-carlo N`: the README's 100 take ~2 min
PIPELINE = ".venv/bin/ovtraj pipeline configs/scenario.yaml"  # README command 1's main job
PROJECT = ("ovtraj", "tasks", "flows")

# The moto S3 server fixture of tests/test_object_store.py, under a name of this module.
moto_s3 = test_object_store.s3


def _bash_block(path: Path, section: str | None = None) -> str:
    """The first bash block of ``path`` (of its section ``## section`` if named)."""
    text = path.read_text(encoding="utf-8")
    if section is not None:
        text = text.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
    found = re.search(r"```bash\n(.*?)```", text, flags=re.DOTALL)
    assert found, f"{path.name}: no bash block"
    return found.group(1)


def _use_commands() -> list[str]:
    """The commands of the README's "Use" section, then docs/commands.md's, comments
    removed, continued lines joined."""
    block = _bash_block(REPO / "README.md", "Use") + _bash_block(REPO / "docs" / "commands.md")
    commands, pending = [], ""
    for line in block.splitlines():
        code = re.sub(r"(^|\s+)#.*$", "", line).strip()
        if code.endswith("\\"):
            pending += code.removesuffix("\\")
        elif code:
            commands.append(" ".join((pending + " " + code).split()))
            pending = ""
    return commands


USE = _use_commands()
# The "Use" commands a non-editable install (`pip install .`) runs too: those that read
# what differs from an editable one, the package data (the shipped scenario and its
# launcher, the reference launch fit, the export settings) and the dependencies (pyerfa:
# export); the main job and what takes its run and plan.
WHEEL_USE = [
    f".venv/bin/ovtraj {command}"
    for command in (
        "paths",
        "rendezvous configs/scenario.yaml --json",
        "pipeline configs/scenario.yaml",
        "plan RUN_ID --pick 0",
        "fly PLAN.json",
        "export PLAN.json --format oem --out plan.oem",
        "verify RUN_ID",
    )
]


def test_the_readme_use_section_is_read_whole():
    assert len(USE) >= 30 and PIPELINE in USE
    assert [c for c in WHEEL_USE if c not in USE] == []
    prefixes = (".venv/bin/ovtraj ", ".venv/bin/python -m flows.")
    assert [c for c in USE if not c.startswith(prefixes)] == []


# -- what the code imports, statically ------------------------------------------------------
def _requirement_closure(requirements: list[str]) -> set[str]:
    """Distributions (canonical names) that ``requirements`` install, recursively, as this
    environment's metadata declares them: markers evaluated here, extras only where named."""
    from importlib import metadata

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    todo = [Requirement(text) for text in requirements]
    seen: set[tuple[str, frozenset[str]]] = set()
    while todo:
        requirement = todo.pop()
        extras = frozenset(requirement.extras)
        name = canonicalize_name(requirement.name)
        if (name, extras) in seen:
            continue
        seen.add((name, extras))
        for text in metadata.distribution(name).requires or []:
            needed = Requirement(text)
            marker = needed.marker
            if marker is None or any(marker.evaluate({"extra": e}) for e in {"", *extras}):
                todo.append(needed)
    return {name for name, _ in seen}


def _imported_top_modules() -> set[str]:
    """Top-level modules that the library, tasks and flows import (anywhere in a file)."""
    names = set()
    for package in PROJECT:
        for path in (REPO / package).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Import):
                    names |= {alias.name.split(".")[0] for alias in node.names}
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names.add(node.module.split(".")[0])
    return names - set(sys.stdlib_module_names) - {"__future__", *PROJECT}


def test_every_package_the_code_imports_is_installed_by_the_runtime_dependencies():
    """Not by the dev extra alone: ``import erfa`` (ovtraj/astro/eme2000.py) once was."""
    from importlib import metadata

    from packaging.utils import canonicalize_name

    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    installed = _requirement_closure(project["dependencies"])
    providers = metadata.packages_distributions()
    missing = {}
    for module in sorted(_imported_top_modules()):
        assert module in providers, f"{module}: imported, but no installed distribution has it"
        if not {canonicalize_name(d) for d in providers[module]} & installed:
            missing[module] = providers[module]
    assert missing == {}, f"imported, not installed by [project] dependencies: {missing}"


# -- README command 1 in a fresh venv --------------------------------------------------------
def _load(path: Path) -> dict[str, Any]:
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def _dump(path: Path, data: dict[str, Any]) -> None:
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")


def _user_folder(folder: Path, configs: Path, checkout: Path | None = None) -> Path:
    """A user's folder with a copy of ``configs`` (to shorten) and, given the ``checkout``
    that is installed, laid out like it: its flows and tasks linked (they are not
    installed)."""
    shutil.copytree(configs, folder / "configs")
    for package in ("flows", "tasks") if checkout else ():
        (folder / package).symlink_to(checkout / package, target_is_directory=True)
    return folder


def _shorten_mission(folder: Path) -> None:
    scenario = folder / "configs" / "scenario.yaml"
    data = _load(scenario)
    mission = data["mission"]
    mission["doe"].update(samples=12, batch_size=6)
    # One round of 2 points, then converged by promise once the surrogates promise less
    # than the verified front's whole hypervolume again: the short loop converges (an
    # unconverged one exits 1 and fails its flow run), so the pipeline, window and flow
    # commands of "Use" are checked for exit 0 as the README runs them.
    mission["verify"].update(
        points_per_iteration=2, max_iterations=1, budget=2, promise_tolerance=1.0
    )
    mission["surrogate"].update(regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3)
    mission["optimize"].update(population=32, generations=40)
    _dump(scenario, data)
    case = folder / "configs" / "cases" / "shuttle_deorbit.yaml"
    data = _load(case)
    data["monte_carlo"].update(runs=4, batch_size=2)
    _dump(case, data)


def _shorten_launch(folder: Path) -> None:
    """tests/test_caching.py's launch fit: five points, a smaller GA, shorter local phases."""
    scenario = folder / "configs" / "scenario.yaml"
    data = _load(scenario)
    shorten_launch_fit(data)
    _dump(scenario, data)


def _base_environment(home: Path, cache: Path) -> dict[str, str]:
    """The caller's environment without its Python, ovtraj, Prefect, Dask, S3 or XDG
    settings, an empty home and the compiled-code cache ``cache`` (``XDG_CACHE_HOME``,
    heyoka's compiled integrators; module notes)."""
    drop = ("PYTHON", "VIRTUAL_ENV", "OVTRAJ_", "PREFECT_", "DASK_", "AWS_", "XDG_")
    env = {k: v for k, v in os.environ.items() if not k.startswith(drop)}
    updates = {"HOME": str(home), "XDG_CACHE_HOME": str(cache)}
    return env | updates | {"PREFECT_SERVER_ANALYTICS_ENABLED": "false"}


def _copy_checkout(source: Path) -> Path:
    """The files a checkout holds, copied to ``source``."""
    for name in _tracked_files():
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / name, source / name)
    return source


def _pip_env() -> dict[str, str]:
    """The caller's environment without its Python settings."""
    return {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}


def _pip(venv: Path, log: Path, *args: str) -> None:
    """``V/bin/pip *args``, with the user's configuration (its indexes), not this venv's;
    its output appended to ``log``."""
    started = time.monotonic()
    with open(log, "ab") as out:
        done = subprocess.run(
            [str(venv / "bin" / "pip"), *args],
            env=_pip_env(),
            stdout=out,
            stderr=subprocess.STDOUT,
            timeout=INSTALL_TIMEOUT_S,
        )
    assert done.returncode == 0, log.read_text(encoding="utf-8", errors="replace")[-3000:]
    print(f"\npip {shlex.join(args)}: {time.monotonic() - started:.0f} s")


def _remove_later(path: Path) -> None:
    """``path`` (the venv: 1.8 GB, ~40,000 files, ~25 s of disk time here) renamed and
    removed by a process of its own, which the session does not wait for."""
    if path.exists():
        trash = path.with_name(f"{path.name}-removed")
        path.rename(trash)
        subprocess.Popen(
            ["rm", "-rf", str(trash)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )


def _user(root: Path, venv: Path, install: str, cache: Path) -> dict[str, Any]:
    """What the commands of an install need: its programs, an empty home, the
    compiled-code cache ``cache``, the workspaces,
    the name of the fixture that runs its main job; ``folders`` to fill in. ``install``
    ("editable", "wheel") is the install its tests need, ``venv_holds`` the one the venv
    holds, shared by both installs' users."""
    home = root / "home"
    home.mkdir()
    return {
        "root": root,
        "bin": venv / "bin",
        "env": _base_environment(home, cache),
        "folders": {},
        "workspaces": {name: root / "workspaces" / name for name in ("cli", "doe", "flows")},
        "main_job": {"editable": "pipeline", "wheel": "wheel_pipeline"}[install],
        "install": install,
    }


def _holds(user: dict[str, Any]) -> None:
    """The venv holds the install ``user`` tests (the module's tests run editable first)."""
    assert user["venv_holds"]["install"] == user["install"], (
        f"a test of the {user['install']} install ran after the venv was given the "
        f"{user['venv_holds']['install']} one: keep the editable tests first in the module"
    )


@pytest.fixture(scope="module")
def user(tmp_path_factory):
    """README command 1's install of a copy of the checkout into a fresh venv, and the
    user's folders. The venv, 1.8 GB, is removed at the end of the module."""
    root = tmp_path_factory.mktemp("user-install")
    venv = root / "venv"
    try:
        source = _copy_checkout(root / "checkout")
        started = time.monotonic()
        subprocess.run(
            [sys.executable, "-m", "venv", str(venv)], check=True, timeout=300, env=_pip_env()
        )
        _pip(venv, root / "pip.log", "install", "-e", str(source))
        print(f"python3 -m venv V && V/bin/pip install -e COPY: {time.monotonic() - started:.0f} s")
        user = _user(root, venv, "editable", root / "cache")
        user["venv_holds"] = {"install": "editable"}
        mission = _user_folder(root / "mission", source / "configs", source)
        _shorten_mission(mission)
        tle = REPO / "tests" / "data" / "targets" / "iss_2019-12-09.tle"
        shutil.copy2(tle, mission / "iss.tle")
        launch = _user_folder(root / "launch", source / "configs", source)
        _shorten_launch(launch)
        user["folders"] = {"mission": mission, "launch": launch}
        yield user
    finally:
        _remove_later(venv)


@pytest.fixture(scope="module")
def wheel_user(user, tmp_path_factory):
    """``pip install COPY`` (not editable) of a second copy of the checkout, in the venv
    of ``user`` once its tests are done, and every copy then deleted: the package alone,
    with the configs and reference data inside it. The venv's dependencies are the ones
    pip resolved for README command 1 from the same pyproject.toml (``pip check``: the
    installed package's requirements are met); the editable install is uninstalled, and
    neither it nor a source tree is left on the venv's path. Its mission folder holds a
    shortened copy of the installed configs (the one a user edits), found as a user finds
    them: by ``ovtraj paths``."""
    root = tmp_path_factory.mktemp("wheel-install")
    venv = user["bin"].parent
    user["venv_holds"]["install"] = "wheel"  # an editable test from here on fails (_holds)
    shutil.rmtree(user["root"] / "checkout")  # the editable install's source tree
    source = _copy_checkout(root / "checkout")
    log = root / "pip.log"
    started = time.monotonic()
    _pip(venv, log, "uninstall", "-y", "ovtraj")
    _pip(venv, log, "install", "--no-deps", str(source))
    _pip(venv, log, "check")
    print(f"V/bin/pip install COPY, deps installed: {time.monotonic() - started:.0f} s")
    shutil.rmtree(source)  # nothing can come from the source tree
    wheel = _user(root, venv, "wheel", Path(user["env"]["XDG_CACHE_HOME"]))
    wheel["venv_holds"] = user["venv_holds"]
    # Nothing of the editable install is left: no __editable__ path file or finder, no
    # entry of the venv's path outside the venv and the interpreter's own library.
    site = subprocess.run(
        [str(venv / "bin" / "python"), "-c", "import sys; print(*sys.path[1:], sep=chr(10))"],
        cwd=root / "home",
        env=wheel["env"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    tops = (venv, Path(sys.base_prefix))
    outside = [p for p in site if not any(Path(p).is_relative_to(top) for top in tops)]
    assert outside == [], site
    (site_packages,) = venv.glob("lib/python*/site-packages")
    assert [p.name for p in site_packages.iterdir() if "__editable__" in p.name] == []
    env = wheel["env"] | {"OVTRAJ_HOME": str(wheel["workspaces"]["cli"])}
    done = _run([str(wheel["bin"] / "ovtraj"), "paths", "--json"], root / "home", env)
    assert done.returncode == 0, done.stdout + done.stderr
    shipped = json.loads(done.stdout)
    assert shipped["source_checkout"] is False, shipped
    wheel["shipped_configs"] = Path(shipped["configs"])
    for where in (wheel["shipped_configs"], Path(shipped["reference"])):
        assert where.is_relative_to(venv) and where.is_dir(), shipped
    mission = _user_folder(root / "mission", wheel["shipped_configs"])
    _shorten_mission(mission)
    wheel["folders"] = {"mission": mission}
    return wheel


def _run(argv: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run(
        argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=COMMAND_TIMEOUT_S
    )


def _printed(output: str, pattern: str) -> str:
    found = re.search(pattern, output, flags=re.MULTILINE)
    assert found, output
    return found.group(1)


def _main_job(user: dict[str, Any]) -> dict[str, Any]:
    """README command 1's main job, from the mission folder: its DoE run and its plan."""
    argv = [str(user["bin"] / "ovtraj"), *PIPELINE.split()[1:]]
    env = user["env"] | {"OVTRAJ_HOME": str(user["workspaces"]["cli"])}
    done = _run(argv, user["folders"]["mission"], env)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return {
        "done": done,
        "RUN_ID": _printed(done.stdout, r"^DoE run (\w+): "),
        "PLAN.json": _printed(done.stdout, r"^plan: (/\S+\.json)$"),
    }


@pytest.fixture(scope="module")
def pipeline(user):
    return _main_job(user)


@pytest.fixture(scope="module")
def wheel_pipeline(wheel_user):
    return _main_job(wheel_user)


@pytest.fixture(scope="module")
def s3_bucket(moto_s3):
    """A bucket on the moto server: the clients' environment and the bucket's name."""
    import boto3

    client = boto3.client(
        "s3",
        endpoint_url=moto_s3["AWS_ENDPOINT_URL"],
        aws_access_key_id=moto_s3["AWS_ACCESS_KEY_ID"],
        aws_secret_access_key=moto_s3["AWS_SECRET_ACCESS_KEY"],
        region_name=moto_s3["AWS_DEFAULT_REGION"],
    )
    client.create_bucket(Bucket="ovtraj-user")
    return {"env": moto_s3, "bucket": "ovtraj-user"}


@pytest.fixture(scope="module")
def installed_cluster(user, s3_bucket, tmp_path_factory):
    """A TLS scheduler and one worker of the installed venv; the worker holds the S3
    credentials and the empty home."""
    cluster = TlsCluster(tmp_path_factory.mktemp("user-dask"))
    dask = str(user["bin"] / "dask")
    scheduler = [dask, "scheduler", "--host", "127.0.0.1", "--port", str(cluster.port)]
    worker = [dask, "worker", cluster.address, "--nthreads", "1", "--name", "worker-1"]
    try:
        with pytest.MonkeyPatch.context() as patch:  # the processes' environment
            for key, value in s3_bucket["env"].items():
                patch.setenv(key, value)
            for key in ("HOME", "XDG_CACHE_HOME"):
                patch.setenv(key, user["env"][key])
            options = [*cluster.tls_options(), "--no-dashboard"]
            cluster.start("scheduler", [*scheduler, "--protocol", "tls", *options])
            cluster.start("worker-1", [*worker, *options])
        cluster.wait_for_workers(1)
        yield cluster
    finally:
        cluster.stop()


def _argv(command: str, user: dict[str, Any], request: pytest.FixtureRequest) -> list[str]:
    """The README command as run here: the venv's programs, the placeholders filled in,
    optional ``[...]`` parts left out, the short Monte Carlo; for an install without a
    checkout (``shipped_configs``), a shipped config file named by its installed path."""
    words = shlex.split(re.sub(r"\s*\[[^\]]*\]", "", command))
    argv = []
    for index, word in enumerate(words):
        if word.startswith(".venv/bin/"):
            word = str(user["bin"] / word.removeprefix(".venv/bin/"))
        elif word in ("RUN_ID", "PLAN.json"):
            word = request.getfixturevalue(user["main_job"])[word]
        elif word == "PREVIOUS.json":
            word = request.getfixturevalue(user["main_job"])["PLAN.json"]
        elif word.startswith("configs/") and "shipped_configs" in user and command != PIPELINE:
            # `ovtraj paths` shows where: the user's folder holds only the main job's
            # shortened copy (a command given no file reads the same shipped one)
            word = str(user["shipped_configs"] / word.removeprefix("configs/"))
        elif word.endswith("://HOST:8786"):
            address = request.getfixturevalue("installed_cluster").address
            assert word.split("://")[0] == address.split("://")[0], f"{word}: not {address}"
            word = address
        elif word == "s3://bucket/prefix":
            word = f"s3://{request.getfixturevalue('s3_bucket')['bucket']}/runs"
        elif index and words[index - 1] == "--monte-carlo":
            word = MONTE_CARLO_RUNS
        else:  # as the README has it
            assert not re.search(r"[A-Z]{3,}|HOST|bucket", word), f"{word}: a placeholder"
        argv.append(word)
    return argv


def _named(argv: list[str]) -> tuple[str | None, str | None]:
    """(the flow module, the ovtraj subcommand) that ``argv`` runs; one of them None."""
    if argv[1] == "-m":
        return argv[2], None
    return None, next(word for word in argv[1:] if not word.startswith("-"))


def _place(
    argv: list[str], user: dict[str, Any], request: pytest.FixtureRequest
) -> tuple[Path, dict[str, str]]:
    """The folder a command runs in and its environment (module notes)."""
    flow, subcommand = _named(argv)
    launch = subcommand in ("launch", "launch-fit") or flow == "flows.launch_fit"
    folder = user["folders"]["launch" if launch else "mission"]
    workspace = "flows" if flow else "doe" if subcommand == "run" else "cli"
    env = user["env"] | {"OVTRAJ_HOME": str(user["workspaces"][workspace])}
    if flow:
        from prefect.settings import PREFECT_API_URL

        # A flow given no config reads the shipped scenario, as the command does;
        # here the shipped configs are the folder's shortened copy.
        env["OVTRAJ_CONFIG_DIR"] = str(folder / "configs")
        request.getfixturevalue("prefect_server")
        prefect_home = str(user["root"] / "prefect-home")
        env |= {"PREFECT_API_URL": PREFECT_API_URL.value(), "PREFECT_HOME": prefect_home}
    if "--dask-address" in argv:
        env |= request.getfixturevalue("installed_cluster").client_environment()
    if any(word.startswith("s3://") for word in argv):
        env |= request.getfixturevalue("s3_bucket")["env"]
    return folder, env


def _check(done: subprocess.CompletedProcess, argv: list[str], root: Path) -> None:
    shown = (
        f"exit {done.returncode}\nstdout:\n{done.stdout[-3000:]}\nstderr:\n{done.stderr[-3000:]}"
    )
    assert done.returncode == 0, shown
    assert "Traceback" not in done.stdout + done.stderr, shown
    if "--json" in argv:
        assert isinstance(json.loads(done.stdout), dict), shown
    printed = {
        Path(path.rstrip(".,:;)]}"))
        for path in re.findall(r"(?<![\w.:/])(/[^\s'\"]+)", done.stdout)
        if path.startswith(str(root))
    }
    if _named(argv)[1] != "paths":  # it names locations, written or not
        assert [p for p in sorted(printed) if not p.exists()] == [], shown


def _run_use_command(command: str, user: dict[str, Any], request: pytest.FixtureRequest) -> None:
    """A command of the "Use" section run by the install ``user`` and checked."""
    _holds(user)
    argv = _argv(command, user, request)
    if command == PIPELINE:
        done = request.getfixturevalue(user["main_job"])["done"]  # run once, by its fixture
    else:
        folder, env = _place(argv, user, request)
        done = _run(argv, folder, env)
    _check(done, argv, user["root"])


@pytest.mark.parametrize("command", USE, ids=[c.removeprefix(".venv/bin/") for c in USE])
def test_each_command_of_the_readme_use_section_runs_from_the_user_install(command, user, request):
    _run_use_command(command, user, request)


@pytest.mark.parametrize(
    "command", WHEEL_USE, ids=[c.removeprefix(".venv/bin/") for c in WHEEL_USE]
)
def test_the_commands_that_need_the_package_data_run_from_a_non_editable_install(
    command, wheel_user, request
):
    _run_use_command(command, wheel_user, request)


def test_every_module_and_dependency_imports_from_the_non_editable_install(wheel_user):
    """Every module of the installed package and every package the code imports (tasks
    and flows too), from a folder with no checkout: a module left out of the wheel or a
    dependency left out of pyproject.toml fails here."""
    _holds(wheel_user)
    modules = sorted(_imported_top_modules())
    program = (
        "import importlib, pkgutil, sys, ovtraj\n"
        "names = [m.name for m in pkgutil.walk_packages(ovtraj.__path__, 'ovtraj.')]\n"
        "for name in names + sys.argv[1:]:\n"
        "    importlib.import_module(name)\n"
        "print(len(names), ovtraj.__file__)\n"
    )
    argv = [str(wheel_user["bin"] / "python"), "-c", program, *modules]
    done = _run(argv, wheel_user["root"] / "home", wheel_user["env"])
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    count, location = done.stdout.split()
    assert Path(location).is_relative_to(wheel_user["bin"].parent), location
    # every module of the checkout's package but the package itself (ovtraj/__init__.py)
    assert int(count) == len(list((REPO / "ovtraj").rglob("*.py"))) - 1
