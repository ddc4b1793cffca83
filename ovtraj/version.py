"""The code version that results are keyed on: package version plus git state.

Cached task results and run ids must change whenever the code that produced them
does. The package version alone does not (it moves only on releases), so the git
commit is added, and when tracked files differ from it, a hash of the diff.
Outside a git checkout the package version stands alone.
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


@lru_cache(maxsize=1)
def code_version() -> str:
    """``<version>+g<commit>[.d<diff hash>]``, or ``<version>`` outside git."""
    commit = _git("rev-parse", "--short=12", "HEAD")
    if not commit:
        return __version__
    version = f"{__version__}+g{commit.strip()}"
    diff = _git("diff", "HEAD", "--no-ext-diff")
    if diff:
        version += ".d" + hashlib.sha256(diff.encode("utf-8")).hexdigest()[:12]
    return version
