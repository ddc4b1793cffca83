"""How the command modules, the flows and the tasks import.

* A module never imports another module's underscore name: what two modules share is a
  public name (``ovtraj/cli/common.py``, or a module named for the idea), documented and
  kept as such, not a private helper that a change in one module breaks in another.
* ``import ovtraj.cli`` (what ``ovtraj --help`` and every command load first) loads no
  solver, run store, pipeline or orchestration: the rule of ``ovtraj/cli/__init__.py``,
  which keeps the heavy imports inside the commands that use them.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys

import pytest

from tests.conftest import REPO

PACKAGES = ("ovtraj/cli", "flows", "tasks")

# What ``ovtraj --help`` must not load: each costs from 10 ms to seconds.
HEAVY = (
    "ovtraj.runs",
    "ovtraj.pipeline",
    "ovtraj.mission",
    "ovtraj.launch",
    "ovtraj.surrogate",
    "ovtraj.optimize",
    "ovtraj.target_sources",
    "ovtraj.tracking.catalog",
    "scipy",
    "heyoka",
    "numba",
    "matplotlib",
    "sklearn",
    "duckdb",
    "prefect",
    "dask",
)


def underscore_imports(source: str) -> list[tuple[int, str]]:
    """``(line, "module.name")`` of every ``from module import _name`` in ``source`` (a
    relative import too; dunder names are no private names)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            module = "." * node.level + (node.module or "")
            for alias in node.names:
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    found.append((node.lineno, f"{module}.{alias.name}"))
    return found


def test_the_check_finds_an_underscore_import():
    source = (
        "from ovtraj.cli.common import app, _load\n"
        "def f():\n"
        "    from .doe import _runner_choice\n"
        "from ovtraj.cli.common import __all__\n"
    )
    assert underscore_imports(source) == [
        (1, "ovtraj.cli.common._load"),
        (3, ".doe._runner_choice"),
    ]


@pytest.mark.parametrize("package", PACKAGES)
def test_no_module_imports_another_modules_underscore_name(package):
    found = [
        f"{path.relative_to(REPO)}:{line} imports {name}"
        for path in sorted((REPO / package).rglob("*.py"))
        for line, name in underscore_imports(path.read_text(encoding="utf-8"))
    ]
    assert found == [], "make the name public where it is defined:\n" + "\n".join(found)


def test_ovtraj_help_loads_no_heavy_module():
    code = (
        "import json, sys\n"
        "import ovtraj.cli\n"
        f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO
    )
    assert json.loads(done.stdout) == []
