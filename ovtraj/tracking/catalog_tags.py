"""The tags of the store's catalogued items: metadata beside an item, never in its
checksummed files (``<store>/catalog/tags/<id>.json``, written by ``ovtraj tag``:
:func:`ovtraj.tracking.catalog.set_tags`), each tag within ``catalog`` of
configs/orchestration.yaml."""

from __future__ import annotations

import json
import re
from pathlib import Path

from ovtraj.formatting import printable
from ovtraj.store.backends import S3Path, location
from ovtraj.store.files import StoreError
from ovtraj.store.seals import read_authenticated
from ovtraj.tracking.catalog_schema import catalog_folder, catalog_settings, checked_id

__all__ = ["TAGS_DIR", "all_tags", "checked_tag", "read_tags", "tag_file", "tags_text"]

TAGS_DIR = "tags"
_TAG_KEY = re.compile(r"[A-Za-z][A-Za-z0-9_.-]*")


def tag_file(root: Path | S3Path, item_id: str) -> Path | S3Path:
    """The tag file of ``item_id`` (checked as an id) in the store ``root``."""
    return catalog_folder(root) / TAGS_DIR / f"{checked_id(item_id, 'id')}.json"


def all_tags(root: Path | S3Path) -> dict[str, dict[str, str]]:
    """Every item's tags, by id; a damaged or foreign tag file counts as none."""
    folder = catalog_folder(root) / TAGS_DIR
    found: dict[str, dict[str, str]] = {}
    for path in sorted(folder.iterdir()) if folder.is_dir() else []:
        if not path.name.endswith(".json"):
            continue
        try:
            found[path.name[:-5]] = read_tags(root, path.name[:-5])
        except StoreError:
            continue  # a damaged or foreign file: no tags (`ovtraj tag` rewrites it)
    return found


def read_tags(store_root: Path | S3Path | str, item_id: str) -> dict[str, str]:
    """The tags of ``item_id`` (empty when it has none); :class:`StoreError` naming the
    file when it is not a tag file: not the item's, tags beyond what ``ovtraj tag``
    accepts (:func:`checked_tag`, ``catalog.tags_per_item``), or, with a store key, a seal
    missing or wrong."""
    path = tag_file(location(store_root), item_id)
    if not path.is_file():
        return {}
    document = read_authenticated(path)
    tags = document.get("tags") if isinstance(document, dict) else None
    if not isinstance(tags, dict) or document.get("id") != item_id:
        raise StoreError(f"{path}: not the tags of {item_id}")
    if len(tags) > catalog_settings().tags_per_item:
        raise StoreError(f"{path}: {len(tags)} tags, more than catalog.tags_per_item")
    for key, value in tags.items():
        try:
            if not isinstance(value, str):
                raise ValueError(f"tag {printable(key)[:80]}: not text")
            checked_tag(key, value)
        except ValueError as err:
            raise StoreError(f"{path}: {err}") from None
    return dict(tags)


def checked_tag(key: str, value: str) -> None:
    """A tag's name and value within ``catalog`` of configs/orchestration.yaml
    (:class:`ValueError` naming what is wrong)."""
    settings = catalog_settings()
    shown = printable(key)[:80]
    if not _TAG_KEY.fullmatch(key) or len(key) > settings.tag_key_max_chars:
        raise ValueError(
            f"tag name {shown!r}: a letter, then letters, digits, '_', '.' or '-', at most "
            f"{settings.tag_key_max_chars} characters (catalog.tag_key_max_chars)"
        )
    if len(value) > settings.tag_value_max_chars or printable(value) != value:
        raise ValueError(
            f"tag {shown}: the value must be printable text of at most "
            f"{settings.tag_value_max_chars} characters (catalog.tag_value_max_chars)"
        )


def tags_text(tags: dict[str, str] | None) -> str:
    """Tags as the catalog's ``tags`` column holds them (a JSON object, keys sorted)."""
    return json.dumps(tags, sort_keys=True) if tags else "{}"
