"""Run the commands of docs/tutorial.md and write their outputs into it.

The tutorial's steps are HTML comments followed by an empty or earlier ``console`` block::

    <!-- tutorial
    run: ovtraj front {run}
    capture: {plan: '^plan: (\\S+\\.json)$'}
    head: 8
    -->

``run`` is one shell command. ``{name}`` is a value captured from an earlier step's output
(``capture``: name -> a regular expression whose first group is the value, searched line by
line) or a port (``prefect_port``, ``dask_port``, ``s3_port``). A command ending in ``&``
is a service: started in its own process group, waited for until ``ready`` holds (``port``
open, ``http`` answering 200, or ``log`` file matching ``match``), and stopped by its
process group's id when the tutorial ends. ``export A=B ...`` sets the environment of the
commands after it. ``head``/``tail`` keep the first/last lines of the shown output, and
``exit`` is the expected exit code (default 0).

The commands run in a copy of the checkout's configs, tools, flows, tasks and prefect.yaml,
at ``HOME/ovtraj`` under a temporary ``HOME``, with the workspace at ``HOME/ovtraj/data``
(a checkout's own, as README command 1 makes it). The outputs show these paths as
``~/ovtraj``. tests/test_tutorial.py runs the same steps on a shortened scenario.

Usage: ``python tools/tutorial.py [--workdir DIR]`` rewrites docs/tutorial.md in place
(about 15 minutes here: three pipelines, two launch fits, a high-fidelity flight).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parents[1]
TUTORIAL = REPO / "docs" / "tutorial.md"
STEP = re.compile(r"<!-- tutorial\n(?P<spec>.*?)\n-->\n```console\n(?P<shown>.*?)```\n", re.S)
COPIED = ("configs", "tools", "flows", "tasks", "prefect.yaml")
DEFAULT_PORTS = {"prefect_port": 4200, "dask_port": 8786, "s3_port": 5000}
COMMAND_TIMEOUT_S = 1800.0  # the longest step, a 48-sample re-plan with its launch fit: ~5 min
SERVICE_TIMEOUT_S = 180.0  # a Prefect server starts in 6-60 s here
STOP_TIMEOUT_S = 30.0


@dataclasses.dataclass(frozen=True)
class Step:
    """One command of the tutorial and how its output is shown."""

    run: str
    capture: dict[str, str]
    head: int | None
    tail: int | None
    exit: int
    ready: dict[str, str] | None

    @property
    def service(self) -> bool:
        return self.run.rstrip().endswith("&")

    @property
    def export(self) -> bool:
        return self.run.startswith("export ")


def steps(text: str) -> list[Step]:
    """The tutorial's steps, in order."""
    found = []
    for match in STEP.finditer(text):
        spec = yaml.safe_load(match["spec"])
        found.append(
            Step(
                run=str(spec["run"]),
                capture=dict(spec.get("capture") or {}),
                head=spec.get("head"),
                tail=spec.get("tail"),
                exit=int(spec.get("exit", 0)),
                ready=spec.get("ready"),
            )
        )
    return found


def _free_port(preferred: int | None = None) -> int:
    with socket.socket() as sock:
        try:
            sock.bind(("127.0.0.1", preferred or 0))
        except OSError:
            sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def prepare(workdir: Path, scenario: Path | None = None) -> tuple[Path, dict[str, str]]:
    """The checkout copy the tutorial runs in, and its environment. ``scenario``: a
    scenario file that replaces configs/scenario.yaml (the tests' short settings)."""
    home = workdir / "home"
    checkout = home / "ovtraj"
    checkout.mkdir(parents=True)
    for name in COPIED:
        source = REPO / name
        if source.is_dir():
            ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
            shutil.copytree(source, checkout / name, ignore=ignore)
        else:
            shutil.copy2(source, checkout / name)
    if scenario is not None:
        shutil.copy2(scenario, checkout / "configs" / "scenario.yaml")
    prefixes = ("PREFECT_", "OVTRAJ_", "AWS_", "DASK_")
    env = {k: v for k, v in os.environ.items() if not k.startswith(prefixes)}
    venv = Path(sys.executable).parent
    env |= {
        "HOME": str(home),
        "OVTRAJ_HOME": str(checkout / "data"),
        "PATH": f"{venv}{os.pathsep}{env.get('PATH', '')}",
        "PYTHONPATH": str(checkout),
        "COLUMNS": "200",
        "NO_COLOR": "1",
    }
    return checkout, env


def _exported(line: str, env: dict[str, str], cwd: Path) -> dict[str, str]:
    """The environment after ``line`` (``export A=B ...``), as bash expands it."""
    done = subprocess.run(
        ["bash", "-c", f"{line} && env -0"], cwd=cwd, env=env, capture_output=True, timeout=30
    )
    if done.returncode != 0:
        raise RuntimeError(f"{line}: exit {done.returncode}: {done.stderr.decode()[-500:]}")
    pairs = (item.split("=", 1) for item in done.stdout.decode().split("\0") if "=" in item)
    return dict(pairs)


def _wait_ready(ready: dict[str, str], cwd: Path, process: subprocess.Popen, what: str) -> None:
    deadline = time.monotonic() + SERVICE_TIMEOUT_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"{what}: exited {process.returncode} before it was ready")
        if "port" in ready:
            with socket.socket() as sock:
                sock.settimeout(1.0)
                if sock.connect_ex(("127.0.0.1", int(ready["port"]))) == 0:
                    return
        elif "http" in ready:
            try:
                with urllib.request.urlopen(ready["http"], timeout=2) as answer:
                    if answer.status == 200:
                        return
            except OSError:
                pass
        elif "log" in ready:
            log = cwd / ready["log"]
            if log.is_file() and re.search(ready["match"], log.read_text(errors="replace")):
                return
        time.sleep(0.5)
    raise RuntimeError(f"{what}: not ready within {SERVICE_TIMEOUT_S:.0f} s")


def _stop(processes: list[subprocess.Popen]) -> None:
    """Stop services' process groups by their ids, all at once (each takes seconds to
    close): SIGINT (as Ctrl-C), then SIGTERM, then SIGKILL to those still running after
    :data:`STOP_TIMEOUT_S`."""
    running = list(processes)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        for process in running:
            try:
                os.killpg(process.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + STOP_TIMEOUT_S
        for process in running:
            try:
                process.wait(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                pass
        running = [process for process in running if process.poll() is None]
        if not running:
            return


def _shown(output: str, step: Step, replacements: list[tuple[str, str]]) -> str:
    """The output as the page shows it: the temporary folders as ``~``, lines without
    trailing blanks, and with ``head``/``tail`` only the first/last lines around ``...``."""
    for old, new in replacements:
        output = output.replace(old, new)
    lines = [line.rstrip() for line in output.rstrip("\n").splitlines()]
    if step.head is None and step.tail is None:
        return "\n".join(lines)
    head, tail = step.head or 0, step.tail or 0
    if head + tail >= len(lines):
        return "\n".join(lines)
    return "\n".join([*lines[:head], "...", *(lines[len(lines) - tail :] if tail else [])])


@contextmanager
def services() -> Iterator[list[subprocess.Popen]]:
    started: list[subprocess.Popen] = []
    try:
        yield started
    finally:
        _stop(started)


def run_steps(
    all_steps: list[Step],
    checkout: Path,
    env: dict[str, str],
    ports: dict[str, int],
    report: Callable[[str], None] = lambda line: None,
    unconverged_ok: bool = False,
) -> list[tuple[str, str]]:
    """Run every step in order; returns (the command as shown, its output as shown). A
    step that exits other than expected raises with the command and its output's end.
    ``unconverged_ok``: a step may exit 1 with a verdict of "not converged" (short
    settings: a loop of one round; the front and plan are stored all the same)."""
    values: dict[str, Any] = dict(ports)
    home = checkout.parent
    # the copy, its home, and this checkout (an editable install's shipped configs)
    replacements = [(str(checkout), "~/ovtraj"), (str(home), "~"), (str(REPO), "~/ovtraj")]
    results = []
    with services() as started:
        for step in all_steps:
            command = step.run.format(**values)
            if unconverged_ok and command.startswith("prefect deployment run mission/"):
                # the flow's way of saying the same: Completed, named "Not converged"
                command += " --param require_converged=false"
            report(f"$ {command}")
            if step.export:
                env = _exported(command, env, checkout)
                output = ""
            elif step.service:
                process = subprocess.Popen(
                    ["bash", "-c", command.rstrip().removesuffix("&")],
                    cwd=checkout,
                    env=env,
                    start_new_session=True,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
                started.append(process)
                ready = {k: str(v).format(**values) for k, v in (step.ready or {}).items()}
                _wait_ready(ready, checkout, process, command)
                output = ""
            else:
                done = subprocess.run(
                    ["bash", "-c", command],
                    cwd=checkout,
                    env=env,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT,
                    text=True,
                    timeout=COMMAND_TIMEOUT_S,
                )
                output = done.stdout
                unconverged = done.returncode == 1 and re.search(
                    r"not converged", output, flags=re.I
                )
                if done.returncode != step.exit and not (unconverged_ok and unconverged):
                    raise RuntimeError(
                        f"{command}: exit {done.returncode}, expected {step.exit}\n{output[-4000:]}"
                    )
                for name, pattern in step.capture.items():
                    found = re.search(pattern, output, flags=re.M)
                    if found is None:
                        raise RuntimeError(f"{command}: no {name} ({pattern}) in its output")
                    values[name] = found.group(1)
            shown_command = command
            for old, new in replacements:
                shown_command = shown_command.replace(old, new)
            results.append((shown_command, _shown(output, step, replacements)))
    return results


def render(text: str, results: list[tuple[str, str]]) -> str:
    """``text`` with each step's console block holding its command and output."""
    pieces = iter(results)

    def block(match: re.Match) -> str:
        command, output = next(pieces)
        body = f"$ {command}\n" + (f"{output}\n" if output else "")
        return f"<!-- tutorial\n{match['spec']}\n-->\n```console\n{body}```\n"

    return STEP.sub(block, text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workdir", type=Path, help="kept afterwards (default: a temporary one)")
    args = parser.parse_args()
    text = TUTORIAL.read_text(encoding="utf-8")
    with tempfile.TemporaryDirectory(prefix="ovtraj-tutorial-") as scratch:
        workdir = args.workdir or Path(scratch)
        checkout, env = prepare(workdir)
        ports = {name: _free_port(port) for name, port in DEFAULT_PORTS.items()}
        results = run_steps(steps(text), checkout, env, ports, report=print)
    TUTORIAL.write_text(render(text, results), encoding="utf-8")
    print(TUTORIAL)


if __name__ == "__main__":
    main()
