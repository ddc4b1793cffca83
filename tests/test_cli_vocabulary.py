"""One vocabulary across the ``ovtraj`` commands: an option name means one thing on every
command, units in the names of limits, the old spellings of renamed options still taken
for one release (one deprecation line on stderr, hidden from the help), and an example in
every command's help that the command line parses.

The old spellings are checked where they take effect, in click's parsing of the command
(the same parameters as the new spellings), and end to end through
:func:`ovtraj.cli.run_command` on paths that end before any work (a refused limit, a
missing run)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
import typer.core
import typer.main
from typer.testing import CliRunner

from ovtraj.cli import app, run_command
from ovtraj.config.export import FORMATS
from ovtraj.runs.preparation import runner_choice
from ovtraj.target_sources import load_scenario
from tests.conftest import DEFAULT_SCENARIO

ROOT = typer.main.get_command(app)
COMMANDS: dict[str, typer.core.TyperCommand] = dict(ROOT.commands)
RUN = "0123456789abcdef"

# (command, the old spelling's words, the new spelling's words, the new names it warns of)
RENAMED = [
    ("pipeline", ["--max-dv", "250"], ["--max-dv-mps", "250"], ["--max-dv-mps"]),
    ("pipeline", ["--min-payload=400"], ["--min-payload-kg=400"], ["--min-payload-kg"]),
    (
        "plan",
        [RUN, "--max-dv", "250", "--min-payload", "400"],
        [RUN, "--max-dv-mps", "250", "--min-payload-kg", "400"],
        ["--max-dv-mps", "--min-payload-kg"],
    ),
    (
        "window",
        ["--days", "2", "--min-payload", "400"],
        ["--days", "2", "--min-payload-kg", "400"],
        ["--min-payload-kg"],
    ),
    ("launch-fit", ["--output", "fits"], ["--out", "fits"], ["--out"]),
    (
        "history",
        ["--target", "ISS-like space target", "--plot", "trend.png"],
        ["--target-name", "ISS-like space target", "--out", "trend.png"],
        ["--target-name", "--out"],
    ),
    ("optimize", ["--config", "other.yaml", RUN], [RUN, "other.yaml"], ["CONFIG"]),
    (
        "optimize",
        [RUN, "--config=other.yaml", "--refit"],
        [RUN, "other.yaml", "--refit"],
        ["CONFIG"],
    ),
]
OLD_SPELLINGS = ("--max-dv", "--min-payload", "--output", "--plot", "--config")

# Option names whose help differs between commands, each with why it is one meaning.
SAME_MEANING = {
    "--runner": "where the work runs: the DoE's batches (run, pipeline) or whole days (window)",
    "--workers": "how many run at once in the --runner's pool: batches, or a window's days",
    "--seed": "the seed of the command's random draws (the DoE's Latin hypercube, the "
    "Monte Carlo's dispersions)",
    "--monte-carlo": "this many dispersed runs: of the plan (fly) or of the study (deorbit-burn)",
    "--out": "the file or folder a command writes, chosen by the user",
}


def _params(name: str, args: list[str]) -> dict:
    """The parameters click parses from ``ovtraj NAME ARGS`` (what the command gets)."""
    with COMMANDS[name].make_context(name, list(args)) as ctx:
        return dict(ctx.params)


@pytest.mark.parametrize(("name", "old", "new", "named"), RENAMED)
def test_an_old_spelling_warns_once_and_parses_as_the_new_one(name, old, new, named, capsys):
    assert _params(name, new) == _params(name, old)
    warned = capsys.readouterr().err.splitlines()
    assert len(warned) == len(named)
    for line, new_name in zip(warned, named, strict=True):
        assert re.fullmatch(rf"--[a-z-]+ is deprecated: .* {re.escape(new_name)}", line), line
    _params(name, new)
    assert capsys.readouterr().err == ""  # the new spelling says nothing


def test_an_old_spelling_reaches_the_command(tmp_path, capsys):
    """End to end, on paths that stop before any work: the old limit is checked under its
    new name, and the old ``--config`` value is the scenario argument (the run id stays
    the run id: the missing run is named)."""
    store = ["--store", str(tmp_path)]
    assert run_command(["plan", RUN, "--max-dv", "inf", *store]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "--max-dv is deprecated: use --max-dv-mps",
        "--max-dv-mps inf: must be a finite number",
    ]
    assert run_command(["window", "--days", "2", "--min-payload", "1e400", *store]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "--min-payload is deprecated: use --min-payload-kg",
        "--min-payload-kg inf: must be a finite number",
    ]
    assert run_command(["optimize", "--config", str(DEFAULT_SCENARIO), RUN, *store]) == 2
    old = capsys.readouterr().err.splitlines()
    assert run_command(["optimize", RUN, str(DEFAULT_SCENARIO), *store]) == 2
    new = capsys.readouterr().err.splitlines()
    assert old == ["--config is deprecated: give it as the argument CONFIG", *new]
    assert len(new) == 1 and f"{RUN}: no such run" in new[0]


def test_old_spellings_are_no_options_and_stay_out_of_the_help():
    runner = CliRunner()
    for name, command in COMMANDS.items():
        names = {opt for param in command.params for opt in param.opts}
        assert not names & set(OLD_SPELLINGS), name
        shown = runner.invoke(app, [name, "--help"], env={"COLUMNS": "200"}).output
        for old in OLD_SPELLINGS:
            assert not re.search(rf"{old}(?![\w-])", shown), (name, old)
    history = runner.invoke(app, ["history", "--help"], env={"COLUMNS": "200"}).output
    assert not re.search(r"--target(?![\w-])", history)


def _options() -> dict[str, list[tuple[str, typer.core.TyperOption]]]:
    found: dict[str, list[tuple[str, typer.core.TyperOption]]] = {}
    for name, command in COMMANDS.items():
        for param in command.params:
            if isinstance(param, typer.core.TyperOption):
                for opt in (*param.opts, *param.secondary_opts):
                    found.setdefault(opt, []).append((name, param))
    return found


def test_an_option_name_means_one_thing_on_every_command():
    """Every option of a name has one type; its help is the same on every command, or the
    name is in SAME_MEANING with the reason its texts differ (and they do differ)."""
    differing = set()
    for opt, uses in _options().items():
        kinds = {(str(p.type_descriptor.annotation), p.is_flag, p.multiple) for _, p in uses}
        assert len(kinds) == 1, f"{opt}: {kinds} on {[n for n, _ in uses]}"
        texts = {p.help for _, p in uses}
        if len(texts) > 1:
            differing.add(opt)
    assert differing == set(SAME_MEANING)


def test_units_in_the_names_of_the_pick_limits():
    for name in ("pipeline", "plan", "window"):
        names = {opt for param in COMMANDS[name].params for opt in param.opts}
        assert {"--max-time-h", "--max-dv-mps", "--min-payload-kg"} <= names, name


def test_workers_size_the_pool_of_run_and_pipeline_as_of_window():
    for name in ("run", "pipeline", "window"):
        (workers,) = [p for p in COMMANDS[name].params if "--workers" in p.opts]
        assert (workers.min, workers.max) == (1, 1024), name
    settings = load_scenario(DEFAULT_SCENARIO).mission.doe
    assert runner_choice(settings, "processes", None, 3).workers == 3
    assert runner_choice(settings, "processes", None).workers == settings.workers
    assert runner_choice(settings, None, None).runner == settings.task_runner
    with pytest.raises(ValueError, match="workers = 0: must be at least 1"):
        runner_choice(settings, "processes", None, 0)  # a flow's parameter, as the option's min


def test_workers_out_of_range_is_one_line_naming_it(tmp_path, capsys):
    for name in ("run", "pipeline"):
        assert run_command([name, "--workers", "0", "--store", str(tmp_path)]) == 2
        (line,) = capsys.readouterr().err.splitlines()
        assert "Invalid value for '--workers'" in line


def test_export_offers_its_formats_as_a_choice(tmp_path, capsys):
    """``--format`` is refused by the parser, naming the choices (in the help too); any
    case of one is taken (the command then reads the plan: here, a missing one)."""
    assert FORMATS == ("oem", "opm")
    plan, out = str(tmp_path / "none.json"), ["--out", str(tmp_path / "x")]
    assert run_command(["export", plan, "--format", "sp3", *out]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "Invalid value for '--format'" in line and "'sp3' is not one of 'oem', 'opm'" in line
    assert run_command(["export", plan, "--format", "OPM", *out]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"{plan}: cannot read the plan file")
    shown = CliRunner().invoke(app, ["export", "--help"], env={"COLUMNS": "200"}).output
    assert "<oem|opm>" in shown
    from ovtraj.mission import ccsds

    assert ccsds.FORMATS is FORMATS  # one definition, the writer's


def _example_spans(command: typer.core.TyperCommand) -> list[str]:
    help_text = command.help or ""
    assert "Example:" in help_text
    example = help_text[help_text.rindex("Example:") :]
    return [span for span in re.findall(r"`([^`]+)`", example) if span.startswith("ovtraj ")]


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_help_ends_with_an_example_that_parses(name):
    command = COMMANDS[name]
    spans = _example_spans(command)
    assert spans and spans[0].split()[1] == name
    for span in spans:
        words = shlex.split(span)[1:]
        shown = words[0]
        with COMMANDS[shown].make_context(shown, words[1:]):
            pass  # a usage error (an unknown option, a missing argument) raises
    after = (command.help or "")[(command.help or "").rindex("Example:") :]
    assert "\n\n" not in after.strip()  # the last paragraph of the help
    rendered = CliRunner().invoke(app, [name, "--help"], env={"COLUMNS": "200"})
    assert rendered.exit_code == 0
    assert re.search(rf"Example: ovtraj {re.escape(name)}\b", rendered.output), rendered.output


def test_the_examples_read_files_of_the_checkout():
    """A path an example names in configs/ is one of the checkout's (it runs as shown)."""
    repo = Path(__file__).resolve().parents[1]
    for name, command in COMMANDS.items():
        for span in _example_spans(command):
            for word in shlex.split(span):
                if word.startswith("configs/"):
                    assert (repo / word).is_file(), (name, word)
