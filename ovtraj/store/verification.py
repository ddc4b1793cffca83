"""What ``ovtraj verify`` finds in one stored item (a run, a Monte Carlo run, a window, the
catalog), and the checks every kind shares: a manifest's or marker's seal and environment
block, a listed file against its recorded size, SHA-256 and schema, the files nothing lists.

The checksums detect accidents; with a store key configured (:mod:`ovtraj.store.seals`) a
document whose seal is missing or wrong is reported apart, as tampered: the files it lists
are still checked against its digests, for accidents.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa

from ovtraj.store.backends import S3Path
from ovtraj.store.environment_block import environment_problem
from ovtraj.store.files import (
    TEMPORARY_SUFFIX,
    Digest,
    StoreError,
    read_bytes,
    read_json,
    read_table,
)
from ovtraj.store.seals import seal_problem

__all__ = ["VerifyReport"]


@dataclass
class VerifyReport:
    """What a verification found: every problem names its file."""

    item_id: str
    checked_files: int = 0
    checked_bytes: int = 0
    problems: list[str] = field(default_factory=list)
    uncovered: list[str] = field(default_factory=list)  # files no marker lists (never read)
    # Manifests and markers whose seal is missing or wrong under the configured store key;
    # empty without a key, since checksums alone cannot tell tampering.
    tampered: list[str] = field(default_factory=list)

    @property
    def run_id(self) -> str:
        return self.item_id

    @property
    def clean(self) -> bool:
        return not self.problems and not self.tampered

    def check_document(self, path: Path | S3Path, document: Any) -> None:
        """A manifest's or marker's seal (with a store key) and environment block."""
        problem = seal_problem(path, document)
        if problem is not None:
            self.tampered.append(problem)
        problem = environment_problem(path, document)
        if problem is not None:
            self.problems.append(problem)

    def read_document(self, path: Path | S3Path) -> Any:
        """A manifest or marker read (bounded) and checked (:meth:`check_document`); None,
        with the problem recorded, when it cannot be read."""
        try:
            document = read_json(path)
        except StoreError as err:
            self.problems.append(str(err))
            return None
        self.check_document(path, document)
        return document

    def check_file(self, path: Path | S3Path, digest: Any, schema: pa.Schema | None = None) -> None:
        """A listed file against its recorded digest (``None``: none recorded) and, for a
        table, its declared schema."""
        try:
            if digest is None:
                raise StoreError(f"{path}: no digest recorded")
            recorded = digest if isinstance(digest, Digest) else Digest.from_json(digest)
            if schema is not None:
                read_table(path, recorded, schema)
            else:
                read_bytes(path, recorded)
        except StoreError as err:
            self.problems.append(str(err))
            return
        except ValueError as err:  # an unusable record of a digest
            self.problems.append(f"{path}: {err}")
            return
        self.checked_files += 1
        self.checked_bytes += recorded.size

    def find_uncovered(self, directory: Path, covered: set[Path]) -> None:
        """Files under ``directory`` that nothing listed (locks and leases left out)."""
        for path in sorted(p for p in directory.rglob("*") if p.is_file()):
            parts = path.relative_to(directory).parts
            if path in covered or parts[0] == "locks" or parts[-1] == ".lock":
                continue
            note = (
                " (temporary file of an interrupted write)"
                if path.name.endswith(TEMPORARY_SUFFIX)
                else ""
            )
            self.uncovered.append(f"{path}{note}")

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.item_id,
            "clean": self.clean,
            "checked_files": self.checked_files,
            "checked_bytes": self.checked_bytes,
            "problems": list(self.problems),
            "tampered": list(self.tampered),
            "uncovered": list(self.uncovered),
        }
