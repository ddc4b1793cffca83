"""Choose the tests the fast tier leaves out, from a measured run of the suite.

Reads a JUnit XML report of the whole suite (``pytest --junitxml=FILE``; each test's
time there includes its fixtures' setup) and writes ``tests/slow_tests.txt``: the longest
tests not marked slow otherwise, taken until the rest fits in the fast tier's budget of
test time (``--budget-s``, summed over both workers). ``tests/conftest.py`` marks the
listed tests ``slow``; each line keeps the seconds it was measured at. A module fixture's
setup is timed in the first test that uses it: when every test using an expensive one
belongs out of the fast tier, mark those tests in their module (tests/test_launch.py's
``solved``), or the listing would only move the setup to the next test.

    python tools/slow_tests.py REPORT.xml [--budget-s 100]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LISTING = REPO / "tests" / "slow_tests.txt"


def measured(report: Path) -> dict[str, float]:
    """Seconds per test id (``tests/test_x.py::name[param]``) in a JUnit report."""
    times: dict[str, float] = {}
    for case in ET.parse(report).getroot().iter("testcase"):
        parts = case.get("classname", "").split(".")
        if len(parts) < 2 or parts[0] != "tests":
            continue
        node = "::".join([f"tests/{parts[1]}.py", *parts[2:], case.get("name", "")])
        skipped = case.find("skipped") is not None
        times[node] = 0.0 if skipped else float(case.get("time") or 0.0)
    return times


def marked_slow() -> set[str]:
    """The tests marked slow otherwise than by the listing: a module's ``pytestmark``, a
    test's own mark, a server fixture (tests/conftest.py ``SERVER_FIXTURES``), as pytest
    collects them with the listing switched off."""
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "--collect-only",
            "-q",
            "-m",
            "slow",
            "-p",
            "no:cacheprovider",
        ],
        cwd=REPO,
        env=os.environ | {"OVTRAJ_SLOW_LISTING": "off"},
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    return {line.strip() for line in done.stdout.splitlines() if "::" in line}


def choose(times: dict[str, float], budget_s: float, marked: set[str]) -> list[tuple[str, float]]:
    """The longest tests, outside ``marked``, whose removal brings the rest within
    ``budget_s``."""
    fast = sorted(
        ((node, t) for node, t in times.items() if node not in marked),
        key=lambda item: -item[1],
    )
    total = sum(t for _, t in fast)
    chosen = []
    for node, t in fast:
        if total <= budget_s:
            break
        chosen.append((node, t))
        total -= t
    return chosen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path)
    parser.add_argument("--budget-s", type=float, default=100.0)
    args = parser.parse_args()
    times = measured(args.report)
    marked = marked_slow()
    chosen = choose(times, args.budget_s, marked)
    lines = [f"{node}  # {t:.1f} s" for node, t in sorted(chosen)]
    header = (
        "# Tests the fast tier (-m 'not slow') leaves out, by measured time (tools/slow_tests.py\n"
        "# chose them from a whole-suite run on 2 cores); tests/conftest.py marks them slow.\n"
    )
    LISTING.write_text(header + "\n".join(lines) + "\n", encoding="utf-8")
    kept = sum(t for n, t in times.items() if n not in marked) - sum(t for _, t in chosen)
    print(f"{LISTING}: {len(chosen)} tests listed; the fast tier's tests take {kept:.0f} s")


if __name__ == "__main__":
    main()
