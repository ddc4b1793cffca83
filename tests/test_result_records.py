"""Prefect task results are plain JSON, and only such records are read (never a pickle).

A shared results folder (or bucket) is writable by whoever shares it. Prefect decodes a
record with the serializer the record names: one naming cloudpickle runs its payload on
every worker that gets a cache hit. The flows' storage (``tasks/results.py``) refuses it,
naming the file, before Prefect reads it; its payload never runs.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import uuid
from collections import Counter
from pathlib import Path

import pytest

from ovtraj.store.result_records import SERIALIZER, RecordError, check_record, record_serializer
from tests.conftest import DEFAULT_SCENARIO
from tests.test_caching import _count, _set_code


class _Payload:
    """Unpickled, runs a shell command that writes ``witness``."""

    def __init__(self, witness: Path) -> None:
        self.witness = witness

    def __reduce__(self):
        return (os.system, (f"touch {self.witness}",))


def _records(folder: Path) -> dict[Path, dict]:
    found = {}
    for path in folder.iterdir():
        try:
            found[path] = json.loads(path.read_bytes())
        except (ValueError, IsADirectoryError):
            continue
    return found


@contextlib.contextmanager
def _refusals():
    """The refusals the task runs log meanwhile (a handler on Prefect's task-run logger,
    whatever its own handlers do with the records)."""
    found: list[str] = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = lambda r: found.append(r.getMessage())
    logger = logging.getLogger("prefect.task_runs")
    logger.addHandler(handler)
    try:
        yield found
    finally:
        logger.removeHandler(handler)
        found[:] = [m for m in found if "task result refused" in m]


def _holds(record: object, value: object) -> bool:
    """Whether ``record`` is a plain JSON result record of ``value``."""
    try:
        return json.loads(record["result"]) == value  # type: ignore[index]
    except (TypeError, KeyError, ValueError):
        return False


def test_the_envelope_is_read_without_decoding_the_result():
    record = {"metadata": {"serializer": {"type": "pickle"}}, "result": "gAR..."}
    assert record_serializer(json.dumps(record).encode(), "r") == "pickle"
    with pytest.raises(RecordError, match=r"r: a Prefect result record of serializer 'pickle'"):
        check_record(json.dumps(record).encode(), "r")
    for junk in (b"\x80\x04K\x01.", b"[1, 2]", b'{"metadata": {}}', b"{" * 100_000):
        with pytest.raises(RecordError, match="not a Prefect result record"):
            check_record(junk, "r")


def test_a_record_naming_pickle_is_refused_and_never_runs(prefect_server, tmp_path, monkeypatch):
    """The rendezvous flow's cached result replaced by a record that names cloudpickle
    (what Prefect itself writes with its default serializer), carrying a payload: the next
    run refuses the record, naming its file in the log, and computes the result again;
    the payload's command never runs."""
    import cloudpickle

    import tasks.rendezvous
    from flows.rendezvous import rendezvous_flow

    calls: Counter = Counter()
    _count(monkeypatch, tasks.rendezvous, "solve_rendezvous", calls)
    _set_code(monkeypatch, f"result-records-{uuid.uuid4().hex}")  # a cache key of its own
    folder = prefect_server["results"]
    before = set(_records(folder)) if folder.is_dir() else set()
    with _refusals() as none:
        first = rendezvous_flow(str(DEFAULT_SCENARIO))
    assert none == [] and calls["solve_rendezvous"] == 1  # a cache miss is no refusal
    expected = json.loads(json.dumps(first))
    ((path, record),) = [
        (p, r) for p, r in _records(folder).items() if p not in before and _holds(r, expected)
    ]
    assert record["metadata"]["serializer"]["type"] == SERIALIZER  # plain JSON data
    # As an attacker with write access to the folder would: the same record, pickled.
    witness = tmp_path / "ran"
    import base64

    record["metadata"]["serializer"] = {"type": "pickle", "picklelib": "cloudpickle"}
    record["result"] = base64.b64encode(cloudpickle.dumps(_Payload(witness))).decode()
    path.write_text(json.dumps(record))
    solved = calls["solve_rendezvous"]
    with _refusals() as refusals:
        again = rendezvous_flow(str(DEFAULT_SCENARIO))
    assert len(refusals) == 1 and str(path) in refusals[0]
    assert "serializer 'pickle', refused" in refusals[0]
    assert not witness.exists()
    # Not served: computed again, the same result, and a plain JSON record in its place.
    assert calls["solve_rendezvous"] == solved + 1 and again == first
    assert json.loads(path.read_bytes())["metadata"]["serializer"]["type"] == SERIALIZER
    assert not witness.exists()
    # The payload was live: Prefect's own reader runs it.
    from prefect._internal.result_records import ResultRecord

    path.write_text(json.dumps(record))
    ResultRecord.deserialize(path.read_bytes())
    assert witness.exists()


def test_expired_results_are_only_records_and_a_link_leaves_its_target(tmp_path, monkeypatch):
    """The flows' clean-up of expired task results (``flows.common.prune_expired_results``)
    deletes expired result records only: not a plain file of the folder, and never the
    file an expired link points to (the link is left alone too)."""
    from flows.common import prune_expired_results
    from ovtraj.config.orchestration import RESULTS_ENV
    from tests.conftest import prefect_record

    folder = tmp_path / "results"
    folder.mkdir()
    record = prefect_record(folder, "0" * 32)
    fresh = prefect_record(folder, "1" * 32)
    plain = folder / "notes.txt"
    plain.write_text("keep me")
    outside = tmp_path / "outside.json"
    outside.write_bytes(record.read_bytes())  # a record too, but outside the folder
    link = folder / ("2" * 32)
    link.symlink_to(outside)
    old = 1e9  # 2001: long expired
    for path in (record, plain, outside):
        os.utime(path, (old, old))
    os.utime(link, (old, old), follow_symlinks=False)
    monkeypatch.setenv(RESULTS_ENV, str(folder))
    assert prune_expired_results() == 1
    assert not record.exists() and fresh.exists() and plain.exists()
    assert link.is_symlink() and outside.exists()
