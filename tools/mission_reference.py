"""Store the mission chain's reference values: data/reference/mission_chain/.

Evaluates the reference designs of ``configs/mission_reference.yaml`` with the shipped
scenario and stores the totals, each stage's impulse and the landing miss, with the code
version that computed them. Run it once, before speed work on the chain; again only for a
deliberate change of the physics, after moving the stored reference aside (it never
overwrites) to ``data/reference/mission_chain_<what it held>/``, where it stays as the
record of what changed (``mission_chain_single_start``: the chain before the rendezvous's
multi-start). ``tests/test_mission_reference.py`` compares the chain with these values.

Run: ``python tools/mission_reference.py`` (prints the path it wrote).
"""

from __future__ import annotations

from ovtraj.mission import reference
from ovtraj.version import code_version


def main() -> None:
    settings = reference.load_settings()
    context = reference.context(settings)
    frame = reference.values(context, reference.designs(context.scenario, settings))
    written = reference.store(
        reference.reference_directory(),
        frame,
        {
            "what": "mission chain reference values",
            "code_version": code_version(),
            "settings": settings.model_dump(mode="json"),
            "feasible": int(frame["feasible"].sum()),
        },
    )
    print(f"stored {len(frame)} designs ({int(frame['feasible'].sum())} feasible) in {written}")


if __name__ == "__main__":
    main()
