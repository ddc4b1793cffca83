"""The code version that results are keyed on: package version plus git state.

Cached task results and run ids must change whenever the code that produced them
does. The package version alone does not (it moves only on releases), so the git
commit is added, and when tracked files differ from it, a hash of the diff. An
installed copy (not a git checkout of its own: a wheel in site-packages, even inside
someone's repository) adds a hash of its Python sources instead: two installs of
different code never share run ids, so a store never hands one of them the other's
results (found when a new install's default pipeline met the plan an older install had
stored under the same ids).
"""

from __future__ import annotations

import hashlib
import subprocess
from functools import lru_cache
from pathlib import Path

from ovtraj import __version__

_SOURCE_ROOT = Path(__file__).resolve().parents[1]


def _git(*args: str) -> str | None:
    try:
        done = subprocess.run(
            ["git", *args],
            cwd=_SOURCE_ROOT,
            capture_output=True,
            check=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.decode("utf-8", errors="replace")


def source_digest(package: Path | None = None) -> str:
    """The first 12 hex digits of the SHA-256 of a package's Python sources (each file's
    path in the package and its bytes, in path order); this package's by default."""
    package = package or Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode("utf-8") + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()[:12]


@lru_cache(maxsize=1)
def code_version() -> str:
    """``<version>+g<commit>[.d<diff hash>]`` in a git checkout of the package, else
    ``<version>+s<source digest>`` (:func:`source_digest`)."""
    top = _git("rev-parse", "--show-toplevel")
    commit = _git("rev-parse", "--short=12", "HEAD")
    if not top or not commit or Path(top.strip()).resolve() != _SOURCE_ROOT:
        return f"{__version__}+s{source_digest()}"
    version = f"{__version__}+g{commit.strip()}"
    diff = _git("diff", "HEAD", "--no-ext-diff")
    if diff:
        version += ".d" + hashlib.sha256(diff.encode("utf-8")).hexdigest()[:12]
    return version
