"""The store layer, at the bottom of ovtraj: nothing here imports a stage, the mission or
the pipeline.

- :mod:`.backends`: where bytes live (a local folder or ``s3://``), conditional writes;
- :mod:`.files`: bounded reads of regular files, digests, atomic writes, JSON;
- :mod:`.records`: declared Parquet schemas and row conversion;
- :mod:`.locks`, :mod:`.seals`: claims and directory locks; HMAC seals of markers;
- :mod:`.products`: a directory of files listed by a marker written last;
- :mod:`.batched`: a run stored batch by batch (the generic store of the Monte Carlo
  studies; the mission DoE's run store is :mod:`ovtraj.runs.store`);
- :mod:`.monte_carlo`: the one driver of such a run, its missing batches flown by whatever
  flier the caller gives (the command's process or pool, the flows' Prefect tasks);
- :mod:`.result_records`: Prefect's task result records, read as data only;
- :mod:`.paths`: where a run store is (``--store``, the config's, the workspace's);
- :mod:`.settings`: the store's limits and waits, given by the configuration layer.
"""
