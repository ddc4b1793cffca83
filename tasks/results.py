"""Prefect task results as plain JSON, read only when they are: a shared result folder
never makes a worker run code it names.

A task's persisted result holds what the task returned: ids, paths and small summaries
(the data itself is in the run store). Prefect's default serializer is cloudpickle, and
its ``json`` serializer imports any class a document names (``__class__``); run stores and
result folders are shared (one S3 bucket for analysts, workers and CI), so either would
let whoever can write there run code on every worker that gets a cache hit.

* :func:`plain_json`: a serializer that writes and reads plain JSON (numpy scalars and
  arrays as numbers and lists; no object hooks): what a task returns must be JSON data.
* :func:`checked_storage`: the local or fsspec storage the flows give their tasks
  (``flows/common.py``), which hands Prefect a record only if it is a regular file no
  larger than ``reads.unrecorded_file_max_mib`` (``configs/orchestration.yaml``) whose
  serializer is :func:`plain_json`'s: Prefect decodes a record with the serializer
  the *record* names, whatever the task was configured with, so a record naming any other
  (``pickle``, ``compressed/pickle``, Prefect's ``json``) is refused before Prefect
  reads it (:func:`ovtraj.store.result_records.check_record`): a warning in the task run's log
  names the file, and Prefect, finding no usable cached result, runs the task again and
  writes a plain JSON record in its place.

With Dask, ``tasks`` travels to the workers by value (``flows/runners.py``), and a pydantic
class rebuilt by cloudpickle is an empty skeleton when Prefect registers it (its
``__dispatch_key__`` is None). So the three classes are defined by running their class
statements once in each process (:func:`_classes`), and their instances pickle as a call
that makes them again there (``__reduce__``), never as the class itself.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from ovtraj.config.orchestration import load_orchestration
from ovtraj.store.files import StoreError, read_bytes
from ovtraj.store.records import json_default
from ovtraj.store.result_records import SERIALIZER, RecordError, check_record
from tasks.process_cache import process_cache

__all__ = ["checked_storage", "plain_json"]

# the bound of every file the stores read without a recorded size
_MAX_BYTES = int(load_orchestration().reads.unrecorded_file_max_mib * 2**20)


def _number(value: Any) -> Any:
    """:func:`ovtraj.store.records.json_default`, refusing in the words of a task result."""
    try:
        return json_default(value)
    except TypeError:
        raise TypeError(
            f"a task result holds a {type(value).__name__}: only JSON data is stored"
        ) from None


def _refusing(read: Callable[[], bytes]) -> bytes:
    """``read()``; a refusal is logged (the task run's log, naming the file) and raised:
    Prefect then takes the cached result for missing, runs the task again and writes a
    plain JSON record in its place."""
    from prefect.exceptions import MissingContextError
    from prefect.logging import get_run_logger

    try:
        return read()
    except (RecordError, StoreError) as err:
        try:
            logger = get_run_logger()
        except MissingContextError:
            logger = logging.getLogger(__name__)
        logger.warning("task result refused: %s", err)
        raise


def _local_record(path: Path) -> bytes:
    """A local record's bytes, read as the stores read an unrecorded file (a regular file,
    no link followed, bounded size; :func:`ovtraj.store.files.read_bytes`), then checked."""
    if not os.path.lexists(path):  # no cached result yet: Prefect's own words, not a refusal
        raise ValueError(f"Path {path} does not exist.")
    return _refusing(lambda: check_record(read_bytes(Path(path)), str(path)))


def _define() -> dict[str, type]:
    """The serializer and the two storages (class statements: see the module)."""
    from typing import Literal  # noqa: F401 (the field's annotation, resolved here)

    from prefect._internal.compatibility.async_dispatch import async_dispatch
    from prefect.filesystems import LocalFileSystem, RemoteFileSystem
    from prefect.serializers import Serializer

    # A class body reads names as LOAD_NAME, which cloudpickle does not ship with a
    # function's globals (and pydantic resolves the annotation in this frame): locals.
    serializer = SERIALIZER

    class PlainJSON(Serializer):
        """JSON without object hooks: a result is data, never a class to import."""

        type: Literal["ovtraj-json"] = serializer

        def dumps(self, obj: Any) -> bytes:
            return json.dumps(obj, default=_number).encode()

        def loads(self, blob: bytes) -> Any:
            return json.loads(blob)

        def __reduce__(self) -> tuple[Any, tuple]:
            return (plain_json, ())

    def reduced(block: Any, kind: str) -> tuple[Any, tuple]:
        saved = (block._block_document_id, block._block_document_name, block._is_anonymous)
        return (_storage, (kind, block.basepath, *saved))

    class CheckedLocalFileSystem(LocalFileSystem):
        """Prefect's local result storage that reads only this project's JSON records."""

        _block_type_name = "ovtraj checked local file system"

        async def aread_path(self, path: str) -> bytes:
            return _local_record(self._resolve_path(path))

        @async_dispatch(aread_path)
        def read_path(self, path: str) -> bytes:
            return _local_record(self._resolve_path(path))

        def __reduce__(self) -> tuple[Any, tuple]:
            return reduced(self, "local")

    class CheckedRemoteFileSystem(RemoteFileSystem):
        """Prefect's fsspec result storage that reads only this project's JSON records."""

        _block_type_name = "ovtraj checked remote file system"

        def _record(self, path: str) -> bytes:
            resolved = self._resolve_path(path)

            def read() -> bytes:
                size = self.filesystem.size(resolved)
                if size is None or size > _MAX_BYTES:
                    raise RecordError(f"{resolved}: not a task result (over {_MAX_BYTES} bytes)")
                with self.filesystem.open(resolved, "rb") as file:
                    return check_record(file.read(_MAX_BYTES + 1), str(resolved))

            if not self.filesystem.exists(resolved):
                raise ValueError(f"Path {resolved} does not exist.")
            return _refusing(read)

        async def aread_path(self, path: str) -> bytes:
            return self._record(path)

        @async_dispatch(aread_path)
        def read_path(self, path: str) -> bytes:
            return self._record(path)

        def __reduce__(self) -> tuple[Any, tuple]:
            return reduced(self, "remote")

    return {"json": PlainJSON, "local": CheckedLocalFileSystem, "remote": CheckedRemoteFileSystem}


def _classes() -> dict[str, type]:
    """This process's classes, defined at its first call."""
    classes = process_cache("task result classes")
    if not classes:
        classes.update(_define())
    return classes


def plain_json() -> Any:
    """The plain JSON serializer of the tasks' results (type :data:`SERIALIZER`)."""
    return _classes()["json"]()


def checked_storage(kind: Literal["local", "remote"], basepath: str) -> Any:
    """The result storage at ``basepath`` (a folder, or an fsspec URL for ``remote``)
    that reads only :func:`plain_json`'s records (unsaved: ``flows/common.py`` saves it)."""
    return _classes()[kind](basepath=basepath)


def _storage(
    kind: str, basepath: str, document_id: Any, name: str | None, anonymous: bool | None
) -> Any:
    """A storage again, in the process that unpickles it: the same saved block."""
    block = checked_storage(kind, basepath)  # type: ignore[arg-type]
    block._block_document_id = document_id
    block._block_document_name = name
    block._is_anonymous = anonymous
    return block
