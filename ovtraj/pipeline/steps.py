"""The two model steps of the pipeline, stored in the run and reused by content.

Layout inside a run's directory::

    surrogates/<fit_id>/    the fitted set (ovtraj.surrogate): models, meta.json,
                            validation.parquet, predictions.parquet, parity-*.png
    fronts/<front_id>/      front.parquet (designs, predicted objectives, p_feasible;
                            :data:`FRONT_SCHEMA`), front.png, meta.json (hypervolume,
                            NSGA-II figures)

Each ``meta.json`` is written last and lists the size and SHA-256 of every file of its
directory (:mod:`ovtraj.store.products`); readers check them and the declared schemas.
A fit or front is computed only in a process on the pinned OpenBLAS kernel
(:func:`ovtraj.environment.require_pinned_kernel`); loading a stored one needs none.

The plots (``parity-*.png``, ``front.png``) are views: with ``views=False`` a step stores
its data without them (the pipeline's rounds do, drawing costing time: it draws the last
round's views in its own directory at the end), and that choice is part of the product's
id.

``fit_id`` hashes the training data (:func:`ovtraj.surrogate.training_data_hash`),
the design bounds, the surrogate settings and the code version; ``front_id`` the
fit id, the optimisation settings and the code version. A stored result is loaded
instead of recomputed; with ``refit`` it is recomputed, compared with the stored one
and never overwritten.
"""

from __future__ import annotations

import concurrent.futures
import hashlib
import json
import multiprocessing
from collections.abc import Callable, Iterator
from concurrent.futures import Executor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.config import Scenario
from ovtraj.environment import require_pinned_kernel
from ovtraj.mission import DESIGN_NAMES
from ovtraj.mission.design_space import bounds_arrays
from ovtraj.optimize import Normalisation, SurrogateFront, surrogate_front
from ovtraj.optimize.objectives import MISSION_OBJECTIVES
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads, mapped, started
from ovtraj.pipeline.data import TrainingData
from ovtraj.pipeline.features import MissionSurrogates, load_surrogates
from ovtraj.pipeline.mission_fit import fit_mission_surrogates
from ovtraj.runs import Run
from ovtraj.runs.runners import limit_threads
from ovtraj.store.backends import location
from ovtraj.store.files import file_digest, write_bytes
from ovtraj.store.layout import ID_HEX_DIGITS
from ovtraj.store.products import Product
from ovtraj.store.records import FLOAT, INT, record_schema, table_from_frame
from ovtraj.surrogate import SurrogateSet, fit_surrogates, training_data_hash

OBJECTIVE_NAMES = tuple(o.name for o in MISSION_OBJECTIVES)
FRONT_SCHEMA = record_schema(
    [
        ("front_index", INT),
        *[(name, FLOAT) for name in DESIGN_NAMES],
        *[(name, FLOAT) for name in OBJECTIVE_NAMES],
        ("p_feasible", FLOAT),
    ],
    required=("front_index", *DESIGN_NAMES),
)
"""``fronts/<front_id>/front.parquet``: the surrogate front (predicted objectives)."""
MARKER = "meta.json"
FRONT_FILE = "front.parquet"


class PipelineError(ValueError):
    """The pipeline cannot proceed (bad input, nothing to fit, a result that differs)."""


class OptimiserStopped(PipelineError):
    """NSGA-II reached its wall-time limit: an unconverged result, not stored."""


def content_id(content: dict[str, Any]) -> str:
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:ID_HEX_DIGITS]


@dataclass
class FitOutcome:
    surrogates: SurrogateSet | MissionSurrogates
    directory: Path
    fit_id: str
    reused: bool  # loaded from the store


@dataclass
class FrontOutcome:
    front: SurrogateFront
    directory: Path
    front_id: str
    reused: bool
    matches_stored: bool | None = None  # refit: the recomputed front equals the stored one


@contextmanager
def fitting_pool(scenario: Scenario, samples: int) -> Iterator[Executor | None]:
    """Processes that fit the surrogate candidates side by side (``fit_step``'s
    ``executor``) for a run of ``samples`` samples: ``mission.doe.workers`` of them once
    the training set is large (``surrogate.large_samples.exact_max_samples``); ``None``
    below, where starting them (~2-3 s of imports each) costs more than the fits, and in
    a daemonic process.

    Spawned, one thread each (the pipeline pool's processes): the same models as fitted
    here, since every candidate is seeded and fitted with one BLAS thread.
    """
    large = scenario.mission.surrogate.large_samples
    workers = scenario.mission.doe.workers
    # A daemonic process (a Dask worker's) may not start children: the fits run in it.
    daemon = multiprocessing.current_process().daemon
    if large is None or workers < 2 or samples <= large.exact_max_samples or daemon:
        yield None
        return
    with concurrent.futures.ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=limit_threads,
        initargs=(EVALUATION_BLAS_THREADS,),
    ) as pool:
        yield pool


def fit_step(
    run: Run,
    data: TrainingData,
    scenario: Scenario,
    code: str,
    *,
    refit: bool = False,
    candidates: dict[str, str] | None = None,
    executor: Executor | None = None,
    views: bool = True,
) -> FitOutcome:
    """Surrogates of the run's samples: loaded when stored, else fitted and stored.

    ``candidates``: an earlier fit's ``selected``, refitted without comparing the
    candidates again (``surrogate.selection: first_fit``); part of the fit's id.
    ``executor``: processes that score the candidates (the same fit; not part of its id).
    ``views``: draw and store the parity plots (see the module notes).
    """
    settings = scenario.mission.surrogate
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    data_hash = training_data_hash(data.designs, {**data.outputs, **data.components}, data.feasible)
    content = {
        "data": data_hash,
        "bounds": [lower.tolist(), upper.tolist()],
        "settings": settings.model_dump(mode="json"),
        "code": code,
    }
    if candidates:
        content["candidates"] = dict(sorted(candidates.items()))
    if not views:
        content["views"] = False  # absent when drawn: the ids stored before stay valid
    fit_id = content_id(content)
    directory = run.directory / "surrogates" / fit_id
    stored = (directory / "meta.json").is_file()
    if stored and not refit:
        return FitOutcome(load_surrogates(directory), directory, fit_id, reused=True)
    require_pinned_kernel()  # fitted here: the kernel's last bits move the Kriging fits
    if settings.phase_input:
        surrogates = fit_mission_surrogates(
            data, scenario, lower, upper, candidates=candidates, executor=executor
        )
    else:
        surrogates = fit_surrogates(
            data.designs,
            data.outputs,
            data.feasible,
            lower,
            upper,
            settings,
            input_names=DESIGN_NAMES,
            sample_ids=data.sample_ids,
            candidates=candidates,
            executor=executor,
        )
    if not stored:
        plots = draw_views(parity_views(surrogates), directory) if views else []
        surrogates.save(
            directory,
            meta={"run_id": run.id, "fit_id": fit_id, "code": code},
            views={path.name: file_digest(path) for path in plots},
        )
    return FitOutcome(surrogates, directory, fit_id, reused=False)


@dataclass(frozen=True)
class View:
    """A plot of a product: its file name and the call that draws its Figure (a
    module-level function and picklable arguments, so any process can draw it)."""

    file: str
    draw: Callable[..., Any]
    arguments: tuple[Any, ...] = ()
    options: dict[str, Any] = field(default_factory=dict)


def view_png(view: View) -> bytes:
    """The view drawn, as PNG bytes (:func:`ovtraj.plots.render.png_bytes`)."""
    from ovtraj.plots.render import png_bytes

    return png_bytes(view.draw(*view.arguments, **view.options))


def draw_views(views: list[View], directory: Path, executor: Executor | None = None) -> list[Path]:
    """Draw ``views`` and write each into ``directory`` (atomically); returns the paths.

    ``executor``: processes that draw them side by side (the pipeline's pool; the files
    are the same bytes); this process writes every file, so the directory may be one the
    processes cannot reach (object storage, another machine's disk).
    """
    return write_views(views, mapped(view_png, [(view,) for view in views], executor), directory)


def start_drawing(views: list[View], executor: Executor | None = None) -> Callable[[], list[bytes]]:
    """Begin drawing ``views`` on one of ``executor``'s processes; returns the call that
    waits for their PNG bytes (:func:`ovtraj.parallel.started`; with no executor, drawn by
    that call). The pipeline draws each round's parity plots this way while NSGA-II runs in
    this process, on a core the pool would leave idle: one process draws them all, leaving
    NSGA-II the other core (on the 2-vCPU test machine NSGA-II still slows by about the
    time saved: docs/optimize.md). :func:`write_views` writes the last round's at the end."""
    drawn = started(views_png, [(views,)], executor)
    return lambda: drawn()[0]


def views_png(views: list[View]) -> list[bytes]:
    """:func:`view_png` of each view, in order, in this process."""
    return [view_png(view) for view in views]


def write_views(views: list[View], images: list[bytes], directory: Path) -> list[Path]:
    """Write each view's PNG bytes into ``directory`` (atomically); returns the paths."""
    paths = []
    for view, image in zip(views, images, strict=True):
        path = location(directory) / view.file
        write_bytes(path, image, replace=True)
        paths.append(path)
    return paths


def parity_views(surrogates: Any) -> list[View]:
    """The parity plots of a fitted set (each of its parts)."""
    from ovtraj.plots.surrogate import parity_figure, parity_file_names

    parts = surrogates.parts if hasattr(surrogates, "parts") else (surrogates,)
    return [
        View(name, parity_figure, (part, output))
        for part in parts
        for output, name in parity_file_names(part).items()
    ]


def front_view(file: str, front: Any, run: Run, scenario: Scenario, title: str) -> View:
    """The plot of a surrogate front (predicted) over the run's feasible samples."""
    from ovtraj.plots.front import front_figure

    options = {
        "surrogate": front.predicted,
        "samples": _feasible_totals(run),
        "title": title,
        "scenario": scenario.name,
        "date": f"epoch {scenario.epoch_utc}",
    }
    return View(file, front_figure, (Normalisation.mission(scenario.mission.optimize),), options)


def front_step(
    run: Run,
    fit: FitOutcome,
    scenario: Scenario,
    code: str,
    *,
    refit: bool = False,
    views: bool = True,
    previous: FrontOutcome | None = None,
) -> FrontOutcome:
    """NSGA-II on the surrogates: loaded when stored, else optimised and stored.

    ``views``: draw and store ``front.png`` (see the module notes). ``previous``: the
    pipeline's previous round's front; with ``optimize.warm_start_generations`` set, NSGA-II
    runs that many generations and its first generation holds that front's designs too
    (after the real front's, when ``seed_with_real_front``), a warm start that is part of
    the front's identity."""
    settings = scenario.mission.optimize
    normalisation = Normalisation.mission(settings)
    content = {"fit": fit.fit_id, "settings": settings.model_dump(mode="json"), "code": code}
    if not views:
        content["views"] = False
    warm = settings.warm_start_generations is not None and previous is not None
    if warm:
        content["warm_from"] = previous.front_id
    front_id = content_id(content)
    product = Product(run.directory / "fronts" / front_id, MARKER)
    directory = product.directory
    if product.exists() and not refit:
        return FrontOutcome(load_front(directory, normalisation), directory, front_id, True)
    require_pinned_kernel()
    initial = _real_front_designs(run, normalisation) if settings.seed_with_real_front else None
    search = settings
    if warm:
        earlier = previous.front.designs[list(DESIGN_NAMES)].to_numpy(dtype=float)
        initial = earlier if initial is None else np.vstack([initial, earlier])
        search = settings.model_copy(update={"generations": settings.warm_start_generations})
    # One BLAS thread, as the fits and the evaluations: the same front in any process.
    with blas_threads(EVALUATION_BLAS_THREADS):
        front = surrogate_front(fit.surrogates, normalisation, search, initial=initial)
    if front.info.get("time_limit_reached"):
        raise OptimiserStopped(f"{front.info['reason']}: no front stored")
    table = table_from_frame(front.to_frame(), FRONT_SCHEMA, "surrogate front")
    if product.exists():
        same = _front_table(product).equals(table)
        return FrontOutcome(front, directory, front_id, False, matches_stored=same)
    meta = {
        "front_id": front_id,
        "fit_id": fit.fit_id,
        "run_id": run.id,
        "code": code,
        "points": len(front),
        "hypervolume": front.hypervolume,
        "nsga2": front.info,
        "settings": settings.model_dump(mode="json"),
        "warm_from": previous.front_id if warm else None,
    }
    with product.writing() as out:
        if out.complete:  # stored meanwhile by another process: compare with it
            same = _front_table(product).equals(table)
            return FrontOutcome(front, directory, front_id, False, matches_stored=same)
        out.write_table(FRONT_FILE, table, FRONT_SCHEMA)
        if views:
            title = f"surrogate front {front_id} (run {run.id})"
            (plot,) = draw_views([front_view("front.png", front, run, scenario, title)], directory)
            out.add(plot.name, file_digest(plot))
        out.finish(meta)
    return FrontOutcome(front, directory, front_id, reused=False)


def _front_table(product: Product) -> pa.Table:
    return product.read_table(FRONT_FILE, FRONT_SCHEMA, product.marker())


def front_frame(directory: Path) -> pd.DataFrame:
    """A stored surrogate front's table (checked against its ``meta.json``)."""
    return _front_table(Product(directory, MARKER)).to_pandas()


def load_front(directory: Path, normalisation: Normalisation) -> SurrogateFront:
    """A stored surrogate front; every file checked (StoreError names a changed one)."""
    product = Product(directory, MARKER)
    meta = product.marker()
    frame = product.read_frame(FRONT_FILE, FRONT_SCHEMA, meta)
    predicted = frame[list(normalisation.names)].reset_index(drop=True)
    return SurrogateFront(
        designs=frame[list(DESIGN_NAMES)].reset_index(drop=True),
        predicted=predicted,
        normalised=normalisation.normalise(predicted.to_numpy(dtype=float)),
        p_feasible=frame["p_feasible"].to_numpy(dtype=float),
        hypervolume=float(meta["hypervolume"]),
        info=dict(meta.get("nsga2") or {}),
    )


def _real_front_designs(run: Run, normalisation: Normalisation) -> np.ndarray:
    """Designs of the run's non-dominated feasible samples (real values)."""
    from ovtraj.optimize import non_dominated

    feasible = _feasible_totals(run)
    if len(feasible) == 0:
        return np.zeros((0, len(DESIGN_NAMES)))
    values = normalisation.normalise(feasible[list(normalisation.names)].to_numpy(dtype=float))
    designs = run.samples().set_index("sample_id").loc[feasible["sample_id"], list(DESIGN_NAMES)]
    return designs.to_numpy(dtype=float)[non_dominated(values)]


def _feasible_totals(run: Run) -> pd.DataFrame:
    totals = run.totals()
    return totals[totals["feasible"].astype(bool)] if len(totals) else totals


def unit_designs(scenario: Scenario, designs: np.ndarray) -> np.ndarray:
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    return (np.asarray(designs, dtype=float) - lower) / (upper - lower)
