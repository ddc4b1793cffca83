"""Which library modules the fast test tier (`pytest -m "not slow"`) exercises.

Runs the fast tier under coverage (2 xdist workers, as the README runs it) and lists
every module of ``ovtraj/`` whose functions the tier never enters: a module counts as
reached when at least one line inside one of its function bodies ran (importing it alone
does not count; numba-compiled bodies are invisible to coverage, so a module counts
through its Python functions). Exit 1 when a module is unreached, so the list can be kept empty.

    python tools/fast_tier_reach.py [--keep DIR]

Needs the ``coverage`` package (the dev extra).
"""

from __future__ import annotations

import argparse
import ast
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "ovtraj"


def body_lines(path: Path) -> set[int]:
    """Line numbers of the statements inside the module's function bodies."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for statement in node.body:
                for inner in ast.walk(statement):
                    if isinstance(inner, ast.stmt):
                        lines.add(inner.lineno)
    return lines


def run_fast_tier(data_dir: Path) -> int:
    """The fast tier under coverage (parallel data files in ``data_dir``); pytest's code."""
    rc = data_dir / ".coveragerc"
    rc.write_text(
        "[run]\nparallel = true\npatch = subprocess\n"
        f"source = {PACKAGE}\ndata_file = {data_dir / '.coverage'}\n",
        encoding="utf-8",
    )
    env = dict(os.environ)
    args = [sys.executable, "-m", "coverage", "run", f"--rcfile={rc}", "-m", "pytest"]
    args += ["-q", "-m", "not slow", "-n", "2", "--dist", "loadfile", "-p", "no:cacheprovider"]
    done = subprocess.run(args, cwd=REPO, env=env, check=False)
    subprocess.run(
        [sys.executable, "-m", "coverage", "combine", f"--rcfile={rc}"],
        cwd=REPO,
        env=env,
        check=True,
        capture_output=True,
    )
    return done.returncode


def executed_lines(data_dir: Path) -> dict[str, set[int]]:
    import coverage

    data = coverage.CoverageData(basename=str(data_dir / ".coverage"))
    data.read()
    return {name: set(data.lines(name) or ()) for name in data.measured_files()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, help="keep the coverage data in this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data_dir = args.keep or Path(tmp)
        data_dir.mkdir(parents=True, exist_ok=True)
        code = run_fast_tier(data_dir)
        ran = executed_lines(data_dir)
    modules = sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)
    unreached = []
    for path in modules:
        bodies = body_lines(path)
        if bodies and not bodies & ran.get(str(path), set()):
            unreached.append(path.relative_to(REPO))
    reached = len(modules) - len(unreached)
    print(f"fast tier (pytest exit {code}): {reached} of {len(modules)} modules entered")
    for path in unreached:
        print(f"  never entered: {path}")
    return 1 if unreached or code else 0


if __name__ == "__main__":
    sys.exit(main())
