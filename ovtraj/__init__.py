"""ovtraj: whole-mission trajectory planning of a small reusable orbital vehicle."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("ovtraj")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"
