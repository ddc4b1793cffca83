"""Natural Earth 1:110m land boundaries -> ``data/reference/coastlines_110m.json``.

Provenance of the coastlines drawn under the ground track (``ovtraj/plots/coastlines.py``).
The source is ``land-110m.json`` of the npm package ``world-atlas`` 2.0.2: Natural Earth
4.1.0's 1:110m land (public domain, https://www.naturalearthdata.com/) as TopoJSON, its
coordinates quantized (``transform``) and delta-encoded. Get it with::

    cd /tmp && npm pack world-atlas@2 && tar xzf world-atlas-2.0.2.tgz
    python tools/make_coastlines.py /tmp/package/land-110m.json   # from the repository root

What is done: every arc of the ``land`` object is decoded to longitude and latitude [deg]
(TopoJSON specification 2.1.5: cumulative sum of the deltas, then ``scale`` and
``translate``); segments lying on the antimeridian (both ends at +-180 deg: the cut edges
of polygons that Natural Earth splits there, not coastline) are left out; every line is cut
where it wraps across +-180 deg (``split_at_wrap``); coordinates are rounded to 0.001 deg
(the source's quantization step is 0.0036 deg in longitude, 0.0017 deg in latitude).
The output is deterministic: the same input gives the same bytes.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from ovtraj.plots.coastlines import COASTLINE_FILE, FORMAT, split_at_wrap

REPO = Path(__file__).resolve().parents[1]
OUTPUT = REPO / "data" / "reference" / COASTLINE_FILE
DECIMALS = 3
ON_ANTIMERIDIAN_DEG = 180.0 - 1e-6


def decode_arcs(topology: dict) -> list[np.ndarray]:
    """Every arc of a quantized TopoJSON topology as an (n, 2) array of lon, lat [deg]."""
    transform = topology.get("transform")
    if transform is None:
        raise ValueError("expected a quantized topology (a 'transform' member)")
    scale = np.array(transform["scale"], dtype=float)
    translate = np.array(transform["translate"], dtype=float)
    return [
        np.cumsum(np.array(arc, dtype=float), axis=0) * scale + translate
        for arc in topology["arcs"]
    ]


def arcs_of(geometry: dict) -> set[int]:
    """Indices of the arcs a (multi)polygon or collection uses (``~i`` is arc i reversed)."""
    if geometry["type"] == "GeometryCollection":
        return set().union(*(arcs_of(g) for g in geometry["geometries"]))
    found: set[int] = set()

    def walk(item: object) -> None:
        if isinstance(item, int):
            found.add(item if item >= 0 else ~item)
        else:
            for part in item:
                walk(part)

    walk(geometry.get("arcs", []))
    return found


def coast_lines(arc: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """One arc without its antimeridian segments, cut at the wrap."""
    on_edge = np.abs(arc[:, 0]) >= ON_ANTIMERIDIAN_DEG
    along = on_edge[:-1] & on_edge[1:]  # segment k joins points k and k+1
    lon, lat = arc[:, 0].copy(), arc[:, 1].copy()
    pieces = []
    start = 0
    for k in [*np.flatnonzero(along), len(arc) - 1]:
        pieces.extend(split_at_wrap(lon[start : k + 1], lat[start : k + 1]))
        start = k + 1
    return pieces


def convert(source: Path) -> dict:
    raw = source.read_bytes()
    topology = json.loads(raw)
    arcs = decode_arcs(topology)
    used = sorted(arcs_of(topology["objects"]["land"]))
    polylines = []
    for index in used:
        for lon, lat in coast_lines(arcs[index]):
            polylines.append(
                {
                    "lon": [round(float(x), DECIMALS) + 0.0 for x in lon],
                    "lat": [round(float(y), DECIMALS) + 0.0 for y in lat],
                }
            )
    return {
        "format": FORMAT,
        "what": "coastlines: Natural Earth 1:110m land boundaries as lon/lat polylines",
        "source": "Natural Earth 1:110m physical vectors, land "
        "(https://www.naturalearthdata.com/downloads/110m-physical-vectors/), "
        "via the npm package world-atlas 2.0.2, file land-110m.json (TopoJSON)",
        "licence": "Natural Earth: public domain "
        "(https://www.naturalearthdata.com/about/terms-of-use/); "
        "world-atlas packaging: ISC, Copyright 2013-2019 Michael Bostock",
        "version": "Natural Earth 4.1.0; world-atlas 2.0.2",
        "source_sha256": hashlib.sha256(raw).hexdigest(),
        "made_by": "tools/make_coastlines.py",
        "units": "degrees: longitude east in [-180, 180], geodetic latitude in [-90, 90]",
        "notes": "antimeridian cut edges left out; lines cut where they wrap across +-180 deg; "
        f"rounded to {10.0**-DECIMALS:g} deg",
        "polylines": polylines,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path, help="world-atlas 2.0.2 land-110m.json")
    parser.add_argument("--output", type=Path, default=OUTPUT, help=f"default: {OUTPUT}")
    args = parser.parse_args(argv)
    data = convert(args.source)
    text = json.dumps(data, separators=(",", ":"), ensure_ascii=True)
    # One polyline per line: small diffs, readable, still compact.
    text = text.replace(',{"lon"', ',\n{"lon"').replace('[{"lon"', '[\n{"lon"')
    args.output.write_text(text + "\n", encoding="utf-8")
    points = sum(len(line["lon"]) for line in data["polylines"])
    print(f"{args.output}: {len(data['polylines'])} polylines, {points} points")
    return 0


if __name__ == "__main__":
    sys.exit(main())
