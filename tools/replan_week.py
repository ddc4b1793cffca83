"""A worked week of nightly re-plans, for docs/tracking.md: its commands and their output.

Seven element sets of the drifting ISS-like target, a day apart (tools/example_tle.py
--nights 7: the scenario's orbit propagated with the project's J2 propagator and fitted as
TLEs), the last one at the scenario epoch; each night the re-plan a `mission/mission-replan`
deployment runs: the launch fit of that element set, then the pipeline. Then the tracking
commands: history, diff of the last two nights, a query, a tag, the lineage.

The scenario is the shipped one with ``target.source_settings.max_age_days`` = 7 (the
shipped 3 days would refuse the first four nights' sets for the launch on 2026-12-01).

Run: ``python tools/replan_week.py WORKDIR`` (27 min on 2 shared cores: seven launch fits
of ~85 s and seven pipelines of ~20 s); writes ``WORKDIR/transcript.md``.
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

import yaml

from ovtraj.config.target import default_source_settings
from ovtraj.paths import config_dir

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def main() -> None:
    work = Path(sys.argv[1]).resolve()
    work.mkdir(parents=True, exist_ok=True)
    env = {
        "OVTRAJ_HOME": str(work / "home"),
        "PATH": f"{BIN}:/usr/bin:/bin",
        "COLUMNS": "160",
        "PYTHONPATH": str(ROOT),
    }
    data = yaml.safe_load((config_dir() / "scenario.yaml").read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(config_dir() / data["launch"]["launcher"])
    settings = default_source_settings().model_dump()
    data["target"]["source_settings"] = dict(settings, max_age_days=7.0)
    (work / "week.yaml").write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    transcript: list[str] = []

    def run(command: str, *, keep: int | None = None) -> str:
        done = subprocess.run(
            shlex.split(command), cwd=work, env=env, capture_output=True, text=True, check=False
        )
        lines = done.stdout.rstrip("\n").splitlines()
        shown = lines if keep is None else lines[-keep:]
        transcript.append(f"$ {command}\n" + "\n".join(shown) + f"\n(exit {done.returncode})\n")
        print(transcript[-1], flush=True)
        if done.returncode not in (0, 1):
            print(done.stderr[-2000:], file=sys.stderr)
        return done.stdout

    python = BIN / "python"
    run(f"{python} {ROOT / 'tools' / 'example_tle.py'} --nights 7 --first-day -6 --out tles")
    for tle in sorted((work / "tles").glob("*.tle")):
        run(f"ovtraj launch-fit week.yaml --target tles/{tle.name}", keep=2)
        run(f"ovtraj pipeline week.yaml --target tles/{tle.name}", keep=4)
    run("ovtraj history --target-name 'ISS-like space target'")
    (work / "transcript.md").write_text("\n".join(transcript), encoding="utf-8")
    print(work / "transcript.md")


if __name__ == "__main__":
    main()
