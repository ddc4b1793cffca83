"""The store as an experiment tracker: figures with units, their diff, the catalog (one
Parquet table queried with SQL), the re-plan history of a target and a plan's lineage
(docs/tracking.md)."""
