"""Package layout of the wheel (the metadata is in pyproject.toml).

The configuration files (``configs/``) and the small reference data
(``data/reference/``) stay top-level folders of the repository and are shipped
inside the package as ``ovtraj/configs`` and ``ovtraj/reference``, so that an
installed ``ovtraj`` finds them (``ovtraj.paths``). The Prefect ``flows/`` and
``tasks/`` folders are entrypoints of a repository checkout, not installed
packages.
"""

from setuptools import find_packages, setup

SHIPPED = {"ovtraj.configs": "configs", "ovtraj.reference": "data/reference"}

setup(
    packages=[*find_packages(include=["ovtraj", "ovtraj.*"]), *SHIPPED],
    package_dir=SHIPPED,
    package_data={name: ["**/*.yaml", "**/*.json", "**/*.parquet"] for name in SHIPPED},
)
