"""ovtraj: whole-mission trajectory planning of a small reusable orbital vehicle."""

# First, before anything imports numpy: OpenBLAS's kernel is chosen when it loads, and every
# machine must store the same bits for a run id (ovtraj.environment).
from ovtraj.environment import pin

pin()

from importlib.metadata import PackageNotFoundError, version  # noqa: E402

try:
    __version__ = version("ovtraj")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"
