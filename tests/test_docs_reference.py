"""Every file, module, command and option the README and docs/ name exists: a path in
backquotes (``ovtraj/...``, ``configs/...``), a dotted name (``ovtraj.runs.ids.checked_id``),
and every ``ovtraj COMMAND --option`` in a code block or a backquoted span, checked against
the repository and the CLI itself (click's command tree of :data:`ovtraj.cli.app`)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest
import typer.main

from ovtraj.cli import app

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
TOP = "ovtraj|flows|tasks|tools|benchmarks|configs|tests|data|docs|\\.ci"
PATH = re.compile(rf"`((?:{TOP})/[A-Za-z0-9_./-]+)`")
DOTTED = re.compile(r"`(ovtraj(?:\.[A-Za-z_][A-Za-z0-9_]*)+)`")
SPAN = re.compile(r"`([^`\n]+)`")
FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)
# ``ovtraj`` as the command a line or span runs: at its start, after a prompt, a pipe,
# ``&&``, ``;`` or ``$(``, with or without a folder (``.venv/bin/ovtraj``).
COMMAND = re.compile(
    r"(?:^|&&|;|\||\$\(|\$ )\s*(?:[\w./-]*/)?ovtraj((?: [a-z][a-z-]*)+)?((?: [^|#\n]*)?)"
)
OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*)")


def _line(text: str, at: int) -> int:
    return text.count("\n", 0, at) + 1


def _names() -> dict[str, object]:
    root = typer.main.get_command(app)
    found: dict[str, object] = {}

    def walk(group: object, prefix: str) -> None:
        for name, command in getattr(group, "commands", {}).items():
            found[f"{prefix}{name}"] = command
            walk(command, f"{prefix}{name} ")

    walk(root, "")
    return found


def _options(command: object) -> set[str]:
    names = {"--help"}
    for param in getattr(command, "params", []):
        names.update(getattr(param, "opts", []))
        names.update(getattr(param, "secondary_opts", []))
    return names


def _command_uses(text: str) -> list[tuple[int, str]]:
    """(offset, text) of each code line or backquoted span that runs ``ovtraj``."""
    uses = []
    for fence in FENCE.finditer(text):
        offset = fence.start(1)
        for line in fence.group(1).splitlines(keepends=True):
            if "ovtraj " in line and not line.lstrip().startswith(("#", "from ", "import ")):
                uses.append((offset, line.split("  #", 1)[0]))
            offset += len(line)
    outside = FENCE.sub(lambda m: " " * len(m.group(0)), text)
    uses += [(m.start(1), m.group(1)) for m in SPAN.finditer(outside) if "ovtraj " in m.group(1)]
    return uses


def _problems(doc: Path) -> list[str]:
    text = doc.read_text(encoding="utf-8")
    name = doc.relative_to(ROOT)
    problems = []
    for match in PATH.finditer(text):
        path = match.group(1).rstrip(".")
        if "*" not in path and "<" not in path and not (ROOT / path).exists():
            problems.append(f"{name}:{_line(text, match.start())}: no file {path}")
    for match in DOTTED.finditer(text):
        parts = match.group(1).split(".")
        for k in range(len(parts), 0, -1):
            try:
                value = importlib.import_module(".".join(parts[:k]))
            except ImportError:
                continue
            try:
                for attr in parts[k:]:
                    value = getattr(value, attr)
            except AttributeError:
                problems.append(f"{name}:{_line(text, match.start())}: no {match.group(1)}")
            break
    commands = _names()
    for offset, use in _command_uses(text):
        for match in COMMAND.finditer(use.strip()):
            words = (match.group(1) or "").split()
            chosen = None
            for k in range(len(words), 0, -1):
                if " ".join(words[:k]) in commands:
                    chosen = " ".join(words[:k])
                    break
            if chosen is None:
                if words and not use.lstrip().startswith(("python", "pip")):
                    problems.append(f"{name}:{_line(text, offset)}: no command `ovtraj {words[0]}`")
                continue
            allowed = _options(commands[chosen])
            rest = " ".join(words[len(chosen.split()) :]) + (match.group(2) or "")
            for option in OPTION.findall(rest):
                if option not in allowed:
                    problems.append(
                        f"{name}:{_line(text, offset)}: `ovtraj {chosen}` has no {option}"
                    )
    return problems


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_file_module_command_and_option_named_exists(doc):
    assert _problems(doc) == []
