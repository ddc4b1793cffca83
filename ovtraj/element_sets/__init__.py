"""Element sets as text: TLE and CCSDS OMM parsed and checked (:mod:`.tle`, :mod:`.omm`),
the result (:mod:`.elements`), its SGP4 ephemeris in the project's inertial frame
(:mod:`.ephemeris`), and a scenario target's inline set parsed once (:mod:`.inline`).

No file, no URL: reading those is :mod:`ovtraj.target_sources`' (above the configuration
models, which validate an inline set through :func:`.inline.inline_elements`).
"""
