"""Prefect flows: the orchestration layer (the library never imports Prefect)."""

import os

# No network here: never let the local Prefect server phone home.
os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
