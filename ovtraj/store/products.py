"""Stored products: data files in one directory and a marker, written last, listing their digests.

A run's pipeline products (surrogate fits, surrogate fronts, pipeline results), the
launch fit and the Monte Carlo batches share one convention with the DoE batches of
:mod:`ovtraj.runs.store`:

- every data file is written with the never-overwriting primitives of
  :mod:`ovtraj.store.files` (a Parquet file exactly of its dataset's declared schema);
- the marker (a JSON document) is written last and lists every file it covers as
  ``"files": {name relative to the directory: {"bytes", "sha256"}}``; a product
  without its marker is incomplete and never read;
- a reader takes the digest from the marker and checks size, SHA-256 and (Parquet)
  the declared schema before parsing; a missing, changed or unlisted file is a
  :class:`~ovtraj.store.files.StoreError` naming it;
- with a store key configured (``OVTRAJ_STORE_KEY``), the marker carries an HMAC seal,
  checked on every read (:mod:`ovtraj.store.seals`): a rewritten marker is refused as tampered.

A writer holds the product directory's lock (``flock`` on the directory itself: no
lock file is left, the kernel releases it when the process ends). While the marker
is missing, a file already there is what an interrupted write left: it is removed
before being written again. Once the marker exists, writing the same content again
is a no-op and other content is refused, as for every stored file.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa

from ovtraj.store.backends import location
from ovtraj.store.environment_block import stamped, unstamped
from ovtraj.store.files import (
    Digest,
    StoreError,
    file_digest,
    read_bytes,
    read_json,
    read_table,
    remove_file,
    write_bytes,
    write_json,
    write_parquet,
)
from ovtraj.store.locks import hold_directory
from ovtraj.store.seals import canonical_json, read_authenticated, write_sealed

__all__ = ["Product", "ProductWriter", "digests_json", "directory_lock"]

# How long a writer waits for another process writing the same product.
LOCK_WAIT_S = 600.0


def digests_json(files: Mapping[str, Digest]) -> dict[str, dict[str, Any]]:
    """A marker's ``files`` mapping (sorted by name)."""
    return {name: files[name].to_json() for name in sorted(files)}


class Product:
    """A product directory and the name of its marker."""

    def __init__(self, directory: str | Path, marker: str) -> None:
        self.directory = location(directory)
        self.marker_name = marker

    @property
    def marker_path(self) -> Path:
        return self.directory / self.marker_name

    def exists(self) -> bool:
        """Whether the product is complete (its marker is stored)."""
        return self.marker_path.is_file()

    def marker(self, expected: Digest | None = None) -> dict[str, Any]:
        """The marker's content (checked against ``expected`` when a parent lists it, and
        its seal when a store key is configured: :mod:`ovtraj.store.seals`)."""
        content = read_authenticated(self.marker_path, expected)
        if not isinstance(content, dict) or not isinstance(content.get("files"), dict):
            raise StoreError(
                f"{self.marker_path}: lists no file digests (not a complete product, or "
                "written by an older version of ovtraj): compute it again"
            )
        return content

    def digest(self, name: str, marker: Mapping[str, Any]) -> Digest:
        """The recorded digest of ``name`` (StoreError naming the marker if it lacks one)."""
        recorded = marker["files"].get(name)
        if recorded is None:
            raise StoreError(f"{self.marker_path}: lists no {name}")
        try:
            return Digest.from_json(recorded)
        except ValueError as err:
            raise StoreError(f"{self.marker_path}: {err}") from None

    def read_bytes(self, name: str, marker: Mapping[str, Any]) -> bytes:
        return read_bytes(self.directory / name, self.digest(name, marker))

    def read_json(self, name: str, marker: Mapping[str, Any]) -> Any:
        return read_json(self.directory / name, self.digest(name, marker))

    def read_table(self, name: str, schema: pa.Schema, marker: Mapping[str, Any]) -> pa.Table:
        return read_table(self.directory / name, self.digest(name, marker), schema)

    def read_frame(self, name: str, schema: pa.Schema, marker: Mapping[str, Any]) -> pd.DataFrame:
        return self.read_table(name, schema, marker).to_pandas()

    @contextmanager
    def writing(self, *, wait_s: float = LOCK_WAIT_S) -> Iterator[ProductWriter]:
        """Hold the product's lock and write it (:class:`ProductWriter`, marker last)."""
        with directory_lock(self.directory, wait_s):
            yield ProductWriter(self, complete=self.exists())


class ProductWriter:
    """Writes a product's files under its lock; :meth:`finish` writes the marker."""

    def __init__(self, product: Product, *, complete: bool) -> None:
        self.product = product
        self.complete = complete  # the marker was already stored when the lock was taken
        self.files: dict[str, Digest] = {}

    def discard(self, name: str) -> None:
        """Remove what an interrupted write left at ``name`` (only while incomplete)."""
        if self.complete:
            return
        remove_file(self.product.directory / name)

    def write_bytes(self, name: str, payload: bytes) -> Digest:
        self.discard(name)
        self.files[name] = write_bytes(self.product.directory / name, payload)
        return self.files[name]

    def write_json(self, name: str, value: Any) -> Digest:
        self.discard(name)
        self.files[name] = write_json(self.product.directory / name, value)
        return self.files[name]

    def write_table(self, name: str, table: pa.Table, schema: pa.Schema) -> Digest:
        self.discard(name)
        self.files[name] = write_parquet(self.product.directory / name, table, schema)
        return self.files[name]

    def add(self, name: str, digest: Digest) -> None:
        """List a file written otherwise (a part product's file, a plot)."""
        self.files[name] = digest

    def finish(self, document: Mapping[str, Any]) -> dict[str, Any]:
        """Write the marker: ``document`` with the digests of every file written or added
        and the environment of this process (sealed when a store key is configured:
        :mod:`ovtraj.store.seals`). A marker stored with the same content is kept as it is,
        with the environment of the process that stored it (:mod:`.environment_block`)."""
        if "files" in document:
            raise ValueError("the marker's 'files' are the writer's own")
        content = stamped({**document, "files": digests_json(self.files)})
        path = self.product.marker_path
        if path.is_file():
            stored = read_authenticated(path)
            if isinstance(stored, dict) and canonical_json(unstamped(stored)) == canonical_json(
                unstamped(content)
            ):
                self.files[self.product.marker_name] = file_digest(path)
                return stored
        self.files[self.product.marker_name] = write_sealed(path, content)
        return content


@contextmanager
def directory_lock(directory: Path, wait_s: float = LOCK_WAIT_S) -> Iterator[None]:
    """Exclusive lock on the product directory itself (:func:`.locks.hold_directory`)."""
    with hold_directory(directory, wait_s=wait_s):
        yield
