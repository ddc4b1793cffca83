"""The store's settings, read here from the configuration files and given to the store.

The store sits below the configuration and reads no configuration file: importing
``ovtraj.config`` hands it :func:`store_settings` (:func:`ovtraj.store.settings.use_settings`),
which it calls at its first need. The figures are ``reads``, ``store_key.min_bytes`` and
``locks`` of ``configs/orchestration.yaml`` and the JSON bounds, the echo length and the
object-store waits of ``configs/io_limits.yaml``, read once per process.
"""

from __future__ import annotations

import functools

from ovtraj.config.io_limits import io_limits
from ovtraj.config.orchestration import load_orchestration
from ovtraj.store.settings import StoreSettings


@functools.cache
def store_settings() -> StoreSettings:
    """The store's settings from the shipped (or ``OVTRAJ_CONFIG_DIR``'s) files, read at the
    first call (a :class:`~ovtraj.errors.ConfigError` naming the file and field if one is
    wrong)."""
    orchestration, limits = load_orchestration(), io_limits()
    reads = orchestration.reads
    return StoreSettings(
        decoded_tables_mib=reads.decoded_tables_mib,
        stored_file_max_mib=reads.stored_file_max_mib,
        unrecorded_file_max_mib=reads.unrecorded_file_max_mib,
        environment_block_max_kib=reads.environment_block_max_kib,
        store_key_min_bytes=orchestration.store_key.min_bytes,
        lock_poll_s=orchestration.locks.poll_s,
        lock_lease_s=orchestration.locks.lease_s,
        json_max_depth=limits.json_max_depth,
        json_number_max_chars=limits.json_number_max_chars,
        echo_max_chars=limits.echo_max_chars,
        s3_connect_timeout_s=limits.s3_connect_timeout_s,
        s3_read_timeout_s=limits.s3_read_timeout_s,
    )
