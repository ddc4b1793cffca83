"""The launch-window scan: one whole-mission pipeline per launch day, the best
plan of each day by the pick's weights, and the best day (``ovtraj window``,
``flows/window.py``; docs/window.md).

- :mod:`.days`: one scenario per launch day;
- :mod:`.scan`: the driver (:func:`~.scan.scan_window`) and where the days run;
- :mod:`.records`: a day's record, checked when read again, and the best day;
- :mod:`.porkchop`: each planned day's plan swept along one design variable;
- :mod:`.report`: the window's tables, plots, HTML page and ``window.json``;
- :mod:`.settings`: ``configs/window.yaml``.

Nothing is imported here: the command line loads the pipeline only when it runs.
"""
