"""The store's settings: how much it reads and keeps, how long it waits on an object store.

The store reads no configuration file: it sits below the configuration layer, which gives
it a function returning its :class:`StoreSettings` (:func:`use_settings`; importing
``ovtraj.config`` gives :func:`ovtraj.config.store_settings.store_settings`, read once per
process from ``configs/orchestration.yaml`` and ``configs/io_limits.yaml``). The store calls
it when it first needs a figure: at a read of a stored file, a JSON text parsed, a store key
checked, an object-store client made.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class StoreSettings:
    """The figures the store uses, each named as in its configuration file."""

    # ``reads`` of configs/orchestration.yaml
    decoded_tables_mib: float  # Arrow memory kept of decoded Parquet files [MiB]
    stored_file_max_mib: float  # largest size a marker may record for a stored file [MiB]
    unrecorded_file_max_mib: float  # largest file read without a recorded size [MiB]
    environment_block_max_kib: float  # largest environment block of a manifest [KiB]
    # ``store_key.min_bytes`` of configs/orchestration.yaml
    store_key_min_bytes: int  # shortest OVTRAJ_STORE_KEY accepted [bytes]
    # ``locks`` of configs/orchestration.yaml
    lock_poll_s: float  # a held lock is tried again after this [s]
    lock_lease_s: float  # an object-store lease not renewed for this long is stale [s]
    # configs/io_limits.yaml
    json_max_depth: int  # deepest nesting of a JSON text parsed [levels]
    json_number_max_chars: int  # longest number in a JSON text parsed [characters]
    echo_max_chars: int  # a value echoed in an error line is cut to this [characters]
    s3_connect_timeout_s: float  # an object-store request's wait for its connection [s]
    s3_read_timeout_s: float  # an object-store request's wait for each read of its answer [s]


# A list, not a global rebound: the one function given (empty until then).
_SOURCE: list[Callable[[], StoreSettings]] = []


def use_settings(source: Callable[[], StoreSettings]) -> None:
    """Give the store its settings: ``source()`` is called at each need (so it should
    keep what it reads). A later call replaces the source; what the store already made
    with the former settings (its kept decoded tables, its S3 client) stays."""
    _SOURCE[:] = [source]


def given_settings() -> StoreSettings:
    """The settings of :func:`use_settings`'s source; RuntimeError if none was given
    (nothing imported ``ovtraj.config``, which gives them)."""
    if not _SOURCE:
        raise RuntimeError(
            "the store's settings were not given: import ovtraj.config (it gives them) or "
            "call ovtraj.store.settings.use_settings"
        )
    return _SOURCE[0]()
