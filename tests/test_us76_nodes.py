"""Provenance of the US76 density nodes above 86 km in ``configs/atmosphere_us76.yaml``.

The nodes not marked ``# Table I entry`` come from ``tools/us76_upper_atmosphere.py``, an
integration of the standard's number-density equations; the marked ones are published
Table I figures. Here the integration is run once and every node is compared with it. How
well the resulting model matches the standard is ``test_atmosphere.py``'s business.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest
import yaml

from ovtraj.paths import config_path

TOOL = Path(__file__).resolve().parents[1] / "tools" / "us76_upper_atmosphere.py"
CONFIG = config_path("atmosphere_us76.yaml")

COMPUTED_REL = 5e-4  # rounding to four significant figures
TABLE_I_REL = 1.5e-3  # the integration agrees with Table I to 0.029 %; 5x margin


def _load_tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("us76_upper_atmosphere", TOOL)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


tool = _load_tool()
NODES = tool.read_config_nodes(CONFIG)


@pytest.fixture(scope="module")
def integrated() -> dict[float, float]:
    """The tool's integration at every node altitude [km] -> density [kg/m^3]."""
    altitudes = [node.altitude_km for node in NODES]
    return dict(zip(altitudes, tool.integrated_density(altitudes), strict=True))


def test_text_reading_matches_yaml():
    with open(CONFIG, encoding="utf-8") as fh:
        listed = yaml.safe_load(fh)["upper_density_nodes_km_kg_m3"]
    assert [(node.altitude_km, node.density_kg_m3) for node in NODES] == [
        (float(z), float(rho)) for z, rho in listed
    ]
    assert any(node.table_i for node in NODES)
    assert not all(node.table_i for node in NODES)


@pytest.mark.parametrize("node", NODES, ids=lambda node: f"{node.altitude_km:g}km")
def test_node_agrees_with_integration(integrated, node):
    rel = TABLE_I_REL if node.table_i else COMPUTED_REL
    deviation = integrated[node.altitude_km] / node.density_kg_m3 - 1.0
    assert abs(deviation) <= rel, f"{node}: integration {integrated[node.altitude_km]:.5e}"


def test_tool_regenerates_the_node_list(capsys):
    # Stricter than the tolerances above: the same altitudes, marks and Table I figures, and
    # every computed node is the integration rounded to four figures.
    assert tool.nodes() == NODES
    assert tool.main(["--check", str(CONFIG)]) == 0
    assert f"{len(NODES)} nodes" in capsys.readouterr().out
