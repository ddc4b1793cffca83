"""The run store: one directory per DoE run under ``data/runs/<run_id>/``.

Layout::

    manifest.json                    run id, parent, created, code and dependency
                                     versions, seed, samples, status, counts, store
                                     format, the digests of config and samples, and
                                     the environment that created the run
    config.json                      resolved scenario (every default filled in)
    samples.parquet                  sample_id and the design variables
    stages/<stage>/part-<k>.parquet  each stage's own rows, keyed by sample_id
    totals/part-<k>.parquet          the mission totals, keyed by sample_id
    trajectories/<stage>/part-<k>.parquet   the batch's trajectory tables as stored
    batches/<k>.json                 written last: batch k is complete; its sample ids,
                                     the size and SHA-256 of every file of the batch,
                                     the batch's timing record, and the environment of
                                     the process that computed it
    locks/                           advisory locks of the processes working on the run

Every Parquet file has its dataset's declared schema (:mod:`ovtraj.runs.schemas`). The
environment blocks (:mod:`ovtraj.store.environment_block`: CPU, BLAS and its kernel,
library versions) are declared too, and are never in a data file nor in the run id: the
same inputs store the same data files on every machine (:mod:`ovtraj.environment`).

Guarantees:

- *Nothing stored is changed.* Files are written to a temporary name and linked into
  place; a stored file is never overwritten (only the manifest, the run's index, is
  replaced atomically, and never when nothing changed).
- *Every read is checked.* Readers take the files a batch marker lists, check their
  size, SHA-256 and schema, and refuse a changed file naming it (:class:`StoreError`);
  files without a marker (an interrupted batch) are never read. :meth:`Run.verify`
  checks a whole run.
- *Tamper evidence, with a key.* The checksums detect accidents only. With a store key
  configured (``OVTRAJ_STORE_KEY``), the manifest and every marker carry an HMAC seal,
  checked on every read: a marker rewritten without the key is refused as tampered
  (:mod:`ovtraj.store.seals`), and through its digests so is every data file it lists.
- *Concurrent writers.* A process working on a run holds the run lock (shared) and
  claims each batch (exclusive lock) before computing it, so two processes never
  compute a batch twice; a killed process's locks are released by the kernel. The
  first writer of a run with no other writer removes the temporary files that
  interrupted writes left. A run whose manifest says ``running`` while no process
  holds its lock was interrupted (:meth:`Run.status`).

The run id (:func:`ovtraj.runs.ids.run_id`) is a content hash of what changes results.
The writer's side of a run (locks, claims, batches written and adopted) is
:mod:`ovtraj.runs.run_writing`; what a batch stores, :mod:`ovtraj.runs.batch_tables`; the
check of a whole run, :mod:`ovtraj.runs.run_verify`.

A child run (``parent``) starts with its parent's samples: the parent's stored
batches are adopted as the child's first batches (hard links where the file system
allows, their digests carried over), so only the new samples are evaluated. Its
manifest says how many batches were adopted (``inherited_batches``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa

from ovtraj.config import Scenario
from ovtraj.config.mission import DoeSettings
from ovtraj.environment import dependency_versions
from ovtraj.mission import STAGES
from ovtraj.runs.batch_tables import part_name
from ovtraj.runs.ids import checked_id, results_hash, run_id
from ovtraj.runs.run_verify import verify_run
from ovtraj.runs.run_writing import MANIFEST_LOCK_WAIT_S, RunWriting, utc_now
from ovtraj.runs.schemas import DATASETS, SCHEMA_VERSION
from ovtraj.store import locks, paths
from ovtraj.store.backends import S3Path, location
from ovtraj.store.environment_block import stamped
from ovtraj.store.files import (
    Digest,
    StoreError,
    marker_files,
    read_json,
    read_table,
    write_json,
    write_parquet,
)
from ovtraj.store.layout import MANIFEST
from ovtraj.store.records import table_from_frame
from ovtraj.store.seals import authenticated, read_authenticated, write_sealed
from ovtraj.store.verification import VerifyReport

__all__ = ["Run", "RunStore", "StoreError"]


class Run(RunWriting):
    """One stored run (its writing methods: :class:`~ovtraj.runs.run_writing.RunWriting`)."""

    def __init__(self, directory: Path | S3Path | str) -> None:
        self.directory = location(directory)
        self.id = self.directory.name

    @property
    def url(self) -> str:
        """The run's absolute location (a path, or an object-store URL): what a worker
        on another machine opens with :meth:`open`."""
        return str(self.directory.resolve())

    @classmethod
    def open(cls, url: str) -> Run:
        """The stored run at ``url`` (from :attr:`url`), checked like :meth:`RunStore.run`."""
        where = location(url)
        return RunStore(where.parent).run(where.name)

    # -- metadata -------------------------------------------------------------------------
    @property
    def manifest(self) -> dict[str, Any]:
        """The manifest, its format checked, and its seal when a store key is configured."""
        return authenticated(self.directory / MANIFEST, self.manifest_document())

    def manifest_document(self) -> dict[str, Any]:
        """The manifest as stored (seal included, not checked), of this store format."""
        manifest = read_json(self.directory / MANIFEST)
        if not isinstance(manifest, dict):
            raise StoreError(f"{self.directory / MANIFEST}: not a run manifest")
        version = manifest.get("schema_version", 1)
        if version != SCHEMA_VERSION:
            raise StoreError(
                f"{self.directory / MANIFEST}: store format {version}; this version of ovtraj "
                f"reads format {SCHEMA_VERSION} (checksummed, declared schemas): run the DoE again"
            )
        return manifest

    def _file_digest(self, name: str) -> Digest:
        try:
            return Digest.from_json(self.manifest["files"][name])
        except (KeyError, TypeError, ValueError):
            raise StoreError(f"{self.directory / MANIFEST}: no digest of {name}") from None

    @property
    def config(self) -> dict[str, Any]:
        return read_json(self.directory / "config.json", self._file_digest("config.json"))

    def samples(self) -> pd.DataFrame:
        path = self.directory / "samples.parquet"
        return read_table(
            path, self._file_digest("samples.parquet"), DATASETS["samples"]
        ).to_pandas()

    def lineage(self) -> list[str]:
        """The run's ancestors, the root (a DoE run) first: recorded in the manifest when
        the run was created, else found by following the stored parents."""
        manifest = self.manifest
        recorded_in = f"{self.directory / MANIFEST}: lineage"
        if "lineage" in manifest:
            lineage = manifest["lineage"]
            if not isinstance(lineage, list):
                raise StoreError(f"{recorded_in} is not a list of run ids")
            return [checked_id(rid, recorded_in) for rid in lineage]
        chain: list[str] = []
        parent = manifest.get("parent")
        while parent and parent not in chain:
            chain.insert(0, checked_id(parent, f"{recorded_in}: parent"))
            try:
                parent = Run(self.directory.parent / parent).manifest.get("parent")
            except (StoreError, OSError):
                break  # a removed ancestor ends what can be followed
        return chain

    def status(self) -> str:
        """The manifest's status; ``interrupted`` when it says running and nobody is."""
        status = self.manifest.get("status")
        if status == "running" and not self.in_use():
            return "interrupted"
        return status

    # -- batches --------------------------------------------------------------------------
    def markers(self) -> dict[int, dict[str, Any]]:
        """Every complete batch's marker, by batch index."""
        folder = self.directory / "batches"
        if not folder.is_dir():
            return {}
        found = {}
        for path in folder.glob("*.json"):
            if not path.stem.isdigit():
                continue
            marker = read_authenticated(path)
            if not isinstance(marker, dict) or not isinstance(marker.get("files"), dict):
                raise StoreError(f"{path}: not a batch marker of store format {SCHEMA_VERSION}")
            marker_files(path, marker)  # names inside the run and usable digests, or refused
            found[int(path.stem)] = marker
        return dict(sorted(found.items()))

    def done_batches(self) -> set[int]:
        folder = self.directory / "batches"
        if not folder.is_dir():
            return set()
        return {int(p.stem) for p in folder.glob("*.json") if p.stem.isdigit()}

    def is_stored(self, batch: int) -> bool:
        return (self.directory / "batches" / f"{batch}.json").is_file()

    def batch_size(self, doe: DoeSettings) -> int:
        """Samples a batch of this run: the size its batches were stored with (the
        manifest's ``batch_size``, or the largest stored batch of a run made before it was
        recorded), else ``doe``'s for its sample count (:meth:`DoeSettings.batch_size_for`).

        A batch's index names its samples only under one size: a run resumed under
        other settings keeps the size it started with."""
        manifest = self.manifest
        recorded = manifest.get("batch_size")
        if isinstance(recorded, int) and not isinstance(recorded, bool) and recorded >= 1:
            return recorded
        inherited = int(manifest.get("inherited_batches", 0))
        own = [len(m["sample_ids"]) for k, m in self.markers().items() if k >= inherited]
        return max(own) if own else doe.batch_size_for(len(self.samples()))

    def batches(self, batch_size: int) -> list[tuple[int, pd.DataFrame]]:
        """Every batch of the run as (index, samples), stored or not.

        The batches adopted from the parent come first, as stored; the other samples
        follow in order, ``batch_size`` at a time.
        """
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        samples = self.samples()
        inherited = int(self.manifest.get("inherited_batches", 0))
        markers = self.markers()
        out: list[tuple[int, pd.DataFrame]] = []
        adopted: set[int] = set()
        for k in range(inherited):
            if k not in markers:
                raise StoreError(f"{self.directory / 'batches' / f'{k}.json'}: missing")
            ids = markers[k]["sample_ids"]
            adopted.update(ids)
            out.append((k, samples[samples["sample_id"].isin(ids)]))
        rest = samples[~samples["sample_id"].isin(adopted)]
        for j, start in enumerate(range(0, len(rest), batch_size)):
            out.append((inherited + j, rest.iloc[start : start + batch_size]))
        return out

    def pending_batches(self, batch_size: int) -> list[tuple[int, pd.DataFrame]]:
        done = self.done_batches()
        return [(k, batch) for k, batch in self.batches(batch_size) if k not in done]

    # -- reading ----------------------------------------------------------------------------
    def _dataset(self, name: str) -> pd.DataFrame:
        """Every marked part of a dataset, checked, in sample order."""
        schema = DATASETS[name]
        tables = []
        for k, marker in self.markers().items():
            relative = f"{name}/{part_name(k)}"
            digest = marker["files"].get(relative)
            if digest is None:
                continue  # no sample of the batch reached this stage
            tables.append(read_table(self.directory / relative, Digest.from_json(digest), schema))
        table = pa.concat_tables(tables) if tables else schema.empty_table()
        frame = table.to_pandas()
        return frame.sort_values("sample_id", kind="stable").reset_index(drop=True)

    def batch_totals(self, batch: int) -> pd.DataFrame:
        """The totals of one stored batch (checked)."""
        marker = self.markers().get(batch)
        if marker is None:
            raise StoreError(f"{self.directory / 'batches' / f'{batch}.json'}: missing")
        relative = f"totals/{part_name(batch)}"
        digest = Digest.from_json(marker["files"][relative])
        return read_table(self.directory / relative, digest, DATASETS["totals"]).to_pandas()

    def stage(self, name: str) -> pd.DataFrame:
        if name not in STAGES:
            raise ValueError(f"stage must be one of {', '.join(STAGES)}; got {name!r}")
        return self._dataset(f"stages/{name}")

    def totals(self) -> pd.DataFrame:
        return self._dataset("totals")

    def trajectory(self, stage: str, sample_id: int) -> pd.DataFrame:
        """One sample's trajectory table of a stage as stored (empty if the stage has none)."""
        dataset = f"trajectories/{stage}"
        for k, marker in self.markers().items():
            if sample_id not in marker["sample_ids"]:
                continue
            relative = f"{dataset}/{part_name(k)}"
            digest = marker["files"].get(relative)
            if dataset not in DATASETS or digest is None:
                return pd.DataFrame()
            frame = read_table(
                self.directory / relative, Digest.from_json(digest), DATASETS[dataset]
            ).to_pandas()
            rows = frame[frame["sample_id"] == sample_id]
            return rows.drop(columns="sample_id").reset_index(drop=True)
        raise StoreError(f"{self.directory}: sample {sample_id} is not stored")

    def summary(self) -> dict[str, Any]:
        manifest = self.manifest
        totals = self.totals()
        feasible = totals[totals["feasible"]] if len(totals) else totals
        summary = {
            "run_id": self.id,
            "parent": manifest.get("parent"),
            "origin": manifest.get("origin"),
            "created_utc": manifest.get("created_utc"),
            "status": self.status(),
            "scenario": manifest.get("scenario"),
            "samples": manifest.get("samples"),
            "stored_batches": len(self.done_batches()),
            "evaluated": len(totals),
            "feasible": len(feasible),
        }
        for column in ("t_total_s", "dv_total_mps", "m_load_kg"):
            summary[f"min_{column}"] = float(feasible[column].min()) if len(feasible) else None
            summary[f"max_{column}"] = float(feasible[column].max()) if len(feasible) else None
        return summary

    # -- checking -----------------------------------------------------------------------------
    def verify(self) -> VerifyReport:
        """Check every file of the run against its recorded digest and schema
        (:func:`~ovtraj.runs.run_verify.verify_run`)."""
        return verify_run(self)


class RunStore:
    """All runs under a root directory (default: the workspace's ``runs/``, ovtraj.store.paths)."""

    def __init__(self, root: str | Path | None = None) -> None:
        self.root = paths.store_root(None, None, root)

    @classmethod
    def for_scenario(
        cls, scenario: Scenario, config: str | Path | None, override: str | Path | None = None
    ) -> RunStore:
        """The scenario's store: ``override`` (``--store``), else ``mission.doe.store``
        relative to the folder of the scenario file ``config``, else the workspace's
        ``runs/``."""
        configured = scenario.mission.doe.store if scenario.mission is not None else None
        base = paths.resolve(config, None).parent if config is not None else None
        return cls(paths.store_root(configured, base, override))

    def run_directories(self) -> list[Path | S3Path]:
        """Every run's directory (one with a manifest), in name order; a hidden one (a
        prune's ``.pruned-*`` being deleted) is not a run."""
        if not self.root.is_dir():
            return []
        return [
            d
            for d in sorted(self.root.iterdir())
            if not d.name.startswith(".") and (d / MANIFEST).is_file()
        ]

    def run(self, run_id: str) -> Run:
        """The stored run ``run_id`` (checked: :func:`checked_id`, then its manifest's format)."""
        directory = self.root / checked_id(run_id)
        if not (directory / MANIFEST).is_file():
            raise StoreError(f"{directory}: no such run (no {MANIFEST})")
        run = Run(directory)
        # Refuses another store format, naming the file; the seal is checked by every read of
        # the manifest, so that `verify` can open a tampered run to report it.
        run.manifest_document()
        return run

    def create(
        self,
        *,
        resolved: dict[str, Any],
        samples: pd.DataFrame,
        seed: int,
        code: str,
        parent: str | None = None,
        origin: str = "latin hypercube",
        lineage: list[str] | None = None,
    ) -> Run:
        """The run of these inputs: created, or the stored one if it exists (same id).

        ``lineage``: the parent's ancestors and the parent, root first (kept in the
        manifest so that a family is known when intermediate runs are pruned)."""
        rid = run_id(resolved, seed, samples, code, parent)
        directory = self.root / rid
        samples = samples.reset_index(drop=True)
        if (directory / MANIFEST).is_file():
            return self._reopen(rid, samples)
        run = Run(directory)
        with locks.hold(run.lock_file("manifest"), wait_s=MANIFEST_LOCK_WAIT_S):
            if (directory / MANIFEST).is_file():  # created meanwhile by another process
                return self._reopen(rid, samples)
            files = {
                "config.json": write_json(directory / "config.json", resolved),
                "samples.parquet": write_parquet(
                    directory / "samples.parquet",
                    table_from_frame(samples, DATASETS["samples"], "samples"),
                    DATASETS["samples"],
                ),
            }
            manifest = {
                "run_id": rid,
                "schema_version": SCHEMA_VERSION,
                "parent": parent,
                "lineage": list(lineage or ([parent] if parent else [])),
                "created_utc": utc_now(),
                "scenario": resolved.get("name"),
                "results_hash": results_hash(resolved),
                "code_version": code,
                "dependencies": dependency_versions(),
                "seed": seed,
                "samples": len(samples),
                "origin": origin,
                "status": "created",
                "evaluated": 0,
                "feasible": 0,
                "files": {name: digest.to_json() for name, digest in files.items()},
            }
            write_sealed(directory / MANIFEST, stamped(manifest), replace=True)
        return run

    def latin_hypercube_run(
        self, resolved: dict[str, Any], seed: int, code: str, *, at_most: int
    ) -> Run | None:
        """The stored run with the most Latin-hypercube samples (at most ``at_most``) of this
        scenario, seed and code: a hypercube run or one extended by further hypercubes."""
        wanted = {"results_hash": results_hash(resolved), "seed": seed, "code_version": code}
        best: tuple[int, str, Run] | None = None
        for directory in self.run_directories():
            try:
                manifest = Run(directory).manifest
            except StoreError:
                continue  # not a run of this format: never extended
            if any(manifest.get(k) != v for k, v in wanted.items()):
                continue
            if manifest.get("origin") != "latin hypercube" or manifest["samples"] > at_most:
                continue
            key = (int(manifest["samples"]), manifest.get("created_utc") or "")
            if best is None or key > best[:2]:
                best = (*key, Run(directory))
        return best[2] if best is not None else None

    def _reopen(self, rid: str, samples: pd.DataFrame) -> Run:
        run = self.run(rid)
        if not run.samples().equals(samples):
            raise StoreError(
                f"{run.directory / 'samples.parquet'}: differs from this run's samples"
            )
        return run

    def catalog(self) -> list[dict[str, Any]]:
        """Every run's summary, newest first; an unreadable run is listed with its error."""
        if not self.root.is_dir():
            return []
        rows = []
        for directory in self.run_directories():
            try:
                rows.append(Run(directory).summary())
            except StoreError as err:
                rows.append({"run_id": directory.name, "status": f"error: {err}"})
        return sorted(rows, key=lambda r: r.get("created_utc") or "", reverse=True)
