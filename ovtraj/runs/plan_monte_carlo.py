"""A mission plan's stored Monte Carlo: the study of the one Monte Carlo driver
(:func:`ovtraj.store.monte_carlo.drive_monte_carlo`) behind ``ovtraj fly PLAN
--monte-carlo N`` and the plan Monte Carlo flow (``flows/mission_monte_carlo.py``).

1. the run ``<store>/<run_id>/`` is created, or the stored one reopened
   (:class:`~ovtraj.mission.montecarlo_store.PlanMonteCarloRun`: its id hashes the plan,
   the dispersions that count for results, the runs, the seed, the code version and the
   force model of a high-fidelity closed loop);
2. the runs it does not hold yet fly in batches of ``batch_size`` consecutive runs, each
   batch storing its own part (:func:`~ovtraj.mission.montecarlo_store.store_plan_batch`):
   one after another in the command's process
   (:class:`~ovtraj.runs.monte_carlo_pool.PoolFlier`), or as Prefect tasks on the flow's
   task runner;
3. ``summary.json`` (:meth:`PlanMonteCarloRun.report`, built from the stored batches
   alone), the run's status in ``run.json``, and the pictures
   (:mod:`ovtraj.plots.montecarlo`) in ``plots/``, their digests listed in ``run.json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ovtraj.config import scenario_from_dict
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.config.force_model import ForceModelSettings
from ovtraj.config.montecarlo_plots import MonteCarloPlotSettings, default_montecarlo_plots
from ovtraj.mission.montecarlo_outcome import MANOEUVRES
from ovtraj.mission.montecarlo_statistics import planned_dv
from ovtraj.mission.montecarlo_store import PlanMonteCarloRun, store_plan_batch
from ovtraj.mission.plan import MissionPlan
from ovtraj.paths import config_path
from ovtraj.plots.montecarlo import LOOPS, LandingPoints, Site, dv_figure, footprint_figure
from ovtraj.plots.render import png_bytes
from ovtraj.store.monte_carlo import BatchJob
from ovtraj.store.paths import store_root

__all__ = ["PICTURES", "PlanMonteCarlo", "monte_carlo_figures", "store_of"]

# The pictures of a run, each stored as plots/<name>.png.
PICTURES = ("landing_footprint", "dv_per_manoeuvre")
_TOTAL = ("total", "dv_total_mps")  # the dV histograms' last panel and its stored column


@dataclass(frozen=True)
class PlanMonteCarlo:
    """What a plan Monte Carlo flies and where it is stored
    (:class:`~ovtraj.store.monte_carlo.MonteCarloStudy`): ``root`` the run store, ``code``
    the code version its id hashes, ``batch_size`` runs per stored part; the closed loop
    under ``force_model``'s sky when given."""

    plan: MissionPlan
    dispersions: DispersionsConfig
    runs: int
    seed: int
    root: Path
    code: str
    batch_size: int
    force_model: ForceModelSettings | None = None

    def open_run(self) -> PlanMonteCarloRun:
        """The run of these inputs: created, or the stored one (same id) reopened."""
        return PlanMonteCarloRun.create(
            self.root,
            plan=self.plan.to_dict(),
            dispersions=self.dispersions.results_content(),
            runs=self.runs,
            seed=self.seed,
            code=self.code,
            force_model=self._force_model(),
        )

    def job(self, run: PlanMonteCarloRun) -> BatchJob:
        """A batch of ``run``: :func:`~ovtraj.mission.montecarlo_store.store_plan_batch` of
        the plan, the dispersions, the run's absolute path, the seed and the force model."""
        return BatchJob(
            store_plan_batch,
            {
                "plan": self.plan.to_dict(),
                "dispersions": self.dispersions.model_dump(mode="json"),
                "run_url": str(run.directory.resolve()),
                "seed": self.seed,
                "force_model": self._force_model(),
            },
        )

    def finish(
        self, run: PlanMonteCarloRun, simulated: int, failures: dict[int, str]
    ) -> dict[str, Any]:
        """The run's report (:meth:`PlanMonteCarloRun.report`, as ``summary.json`` holds it)
        with what this pass adds: ``directory`` (absolute), ``simulated_runs``, ``plots``
        (the pictures' absolute paths) and ``failed_batches`` (a line for each batch that
        failed; the stored ones are kept and a new pass flies only the missing runs)."""
        report = run.report()
        run.write_summary(report)
        pictures = monte_carlo_figures(run)
        plots = run.write_plots({f"{name}.png": png_bytes(pictures[name]) for name in PICTURES})
        failed = [f"runs from {k}: {why}" for k, why in sorted(failures.items())]
        run.update_info(status=report["status"], failures=failed)
        return {
            **report,
            "directory": str(run.directory.absolute()),
            "simulated_runs": simulated,
            "plots": [str(p.absolute()) for p in plots],
            "failed_batches": failed,
        }

    def _force_model(self) -> dict[str, Any] | None:
        force_model = self.force_model
        return None if force_model is None else force_model.model_dump(mode="json")


def store_of(
    dispersions: DispersionsConfig, dispersions_file: Path | None, override: str | None = None
) -> Path:
    """The run store of a plan Monte Carlo: ``override`` (the flow's ``store``), else the
    dispersions file's ``execution.store`` (relative to that file's folder; the shipped
    ``configs/dispersions.yaml`` when ``dispersions_file`` is None), else the workspace's
    ``runs/``, which ``ovtraj runs`` and ``ovtraj history`` read."""
    read = config_path("dispersions.yaml") if dispersions_file is None else dispersions_file
    return store_root(dispersions.execution.store, Path(read).resolve().parent, override)


def monte_carlo_figures(
    run: PlanMonteCarloRun, settings: MonteCarloPlotSettings | None = None
) -> dict[str, Any]:
    """The pictures of the stored run by name (:data:`PICTURES`), as Figures, drawn from
    its config and batches alone: the landing footprint of each loop's landed runs about
    the scenario's landing site, with the plan's stated miss and the site's runway
    (``configs/montecarlo_plots.yaml``), and the dV each manoeuvre spent against the plan."""
    settings = settings or default_montecarlo_plots()
    info = run.info
    plan = MissionPlan.model_validate(run.config["plan"])
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    frame = run.results()
    by_loop = {loop: frame[frame["loop"] == loop] for loop in LOOPS}
    points = {}
    for loop, rows in by_loop.items():
        landed = rows[rows["landed"].astype(bool) & rows["landing_latitude_deg"].notna()]
        points[loop] = LandingPoints(
            runs=len(rows),
            latitude_deg=landed["landing_latitude_deg"].to_numpy(dtype=float),
            longitude_deg=landed["landing_longitude_deg"].to_numpy(dtype=float),
        )
    landing = scenario.reentry.landing_site
    site = Site(landing.name, landing.latitude_deg, landing.longitude_deg, scenario.earth.radius)
    title = (
        f"{scenario.name}: plan Monte Carlo {run.id} ({info['runs']} runs, seed "
        f"{info['seed']}, {info.get('fidelity', 'j2')} sky)"
    )
    spent = {
        name: {loop: rows[column].dropna().to_numpy(dtype=float) for loop, rows in by_loop.items()}
        for name, column in (*MANOEUVRES.items(), _TOTAL)
    }
    return {
        "landing_footprint": footprint_figure(
            points,
            site,
            plan.terminal.stated_miss_m,
            settings.runways.get(landing.name),
            settings.footprint.zoom_half_width_stated_miss,
            f"landing footprint: {title}",
        ),
        "dv_per_manoeuvre": dv_figure(
            spent, dict(planned_dv(plan)), f"dV per manoeuvre [m/s]: {title}"
        ),
    }
