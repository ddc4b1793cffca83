"""Stable names of a target's history: its Prefect artifact key and plot file name."""

from __future__ import annotations

import re

__all__ = ["history_key"]

# Prefect's artifact keys: lowercase letters, digits and dashes.
_NOT_KEY = re.compile(r"[^a-z0-9]+")
_MAX_CHARS = 60  # a key a person can read in the UI's artifact list


def history_key(target: str) -> str:
    """``history-<target, lowercase, dashes>``: e.g. ``history-iss-like-space-target``."""
    slug = _NOT_KEY.sub("-", target.lower()).strip("-")[:_MAX_CHARS].strip("-")
    return f"history-{slug or 'target'}"
