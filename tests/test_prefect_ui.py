"""The Prefect UI shows the flows' plots themselves (issue 24, point 6).

A tiny flow run calls the flows' publishing functions (``flows/pipeline.py:_publish``,
``flows/surrogate.py:publish_validation``) on a front plot drawn by the project's plot
code; headless chromium then opens each markdown artifact's page in the UI of a real
Prefect server. The rendered DOM must hold an ``<img>`` whose ``src`` is the PNG itself
as a ``data:image/png;base64`` URI, in both UIs of Prefect 3.9 (``/v2``, the default,
and ``/``), with the file's path as its caption; a screenshot must show the plot's
points painted on the page.

The session's ``prefect_server`` fixture cannot serve a UI: Prefect's test harness runs
an ephemeral server (``PREFECT__SERVER_EPHEMERAL=1``), whose app never mounts the UI.
This module starts ``prefect server start`` the way tests/test_deployments.py does, with
its helpers (a free port of 127.0.0.1, its own ``PREFECT_HOME``, no analytics, no
``PREFECT_*`` variable inherited, stopped by its process group), with the UI on and the
UI's static build copied into a temporary folder (not into the installed package).
Skipped only when ``chromium`` is not installed (``.ci/run`` installs it).
"""

from __future__ import annotations

import dataclasses
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pandas as pd
import pytest

from ovtraj.plots.embed import png_data_uri
from tests.conftest import REPO
from tests.test_deployments import _stop, _tail, prefect_server

CHROMIUM = shutil.which("chromium")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="no chromium on PATH (.ci/run installs it: apt-get install chromium)"
)

PUBLISH_TIMEOUT_S = 120.0
CHROMIUM_TIMEOUT_S = 60.0
RENDER_BUDGET_MS = 15000  # chromium's virtual time for the page's scripts and API calls
DUMP_ATTEMPTS = 3
KEYS = ("mission-plan", "surrogate-parity-plots")
UIS = {"v2": "/v2", "v1": ""}  # Prefect 3.9 serves both; /v2 is the default one
HTML = {"Accept": "text/html"}  # a browser's navigation: the UI's index.html
RED = np.array([214, 39, 40])  # matplotlib's C3: the verified front's points

# The flow run: both publishing functions on the plot's folder (one PNG, front.png).
PUBLISH = """
import sys
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
from prefect import flow

from flows.pipeline import _publish
from flows.surrogate import publish_validation
from ovtraj.pipeline import PipelineResult

directory = Path(sys.argv[1])


@flow(name="ui-artifacts")
def publish() -> None:
    front = pd.DataFrame({"sample": [0, 1], "t_total_s": [9000.0, 12000.0]})
    result = PipelineResult("ui", directory, "doe", "final", front, front, {"hypervolume": 0.5})
    plan = {"json": str(directory / "plan.json"), "yaml": str(directory / "plan.yaml")}
    _publish(result, {**plan, "plots": []})
    validation = [{"model": "t_total_s", "candidate": "kriging", "selected": True}]
    summary = {"directory": str(directory), "fit_id": "ui", "validation": validation}
    publish_validation(summary, SimpleNamespace(id="ui"))


publish()
"""


@dataclasses.dataclass(frozen=True)
class UIServer:
    address: str
    env: dict[str, str]
    root: Path


@dataclasses.dataclass(frozen=True)
class Published:
    png: Path
    artifacts: dict[str, Any]  # key -> prefect.client.schemas.objects.Artifact


@pytest.fixture(scope="module")
def ui_server(tmp_path_factory):
    """A real Prefect server that serves its UI, in a temporary folder of its own."""
    root = tmp_path_factory.mktemp("prefect-ui")
    ui = {"PREFECT_SERVER_UI_ENABLED": "true", "PREFECT_UI_STATIC_DIRECTORY": str(root / "ui")}
    with prefect_server(root, **ui) as (address, env, log):
        for path in UIS.values():
            page = httpx.get(f"{address}{path}/artifacts", headers=HTML, timeout=10)
            assert page.status_code == 200 and "<script" in page.text, (
                f"no UI at {address}{path}/ (HTTP {page.status_code}): is the UI's static "
                f"build in the installed prefect?\n{_tail(log)}"
            )
        yield UIServer(address=address, env=env, root=root)


@pytest.fixture(scope="module")
def published(ui_server, scenario):
    """Run the tiny flow on a front plot drawn by ovtraj.plots.front; read its artifacts."""
    from prefect.client.orchestration import SyncPrefectClient
    from prefect.client.schemas.filters import ArtifactFilter, ArtifactFilterKey

    from ovtraj.optimize.objectives import Normalisation
    from ovtraj.plots.front import front_plot

    directory = ui_server.root / "plots"
    directory.mkdir()
    normalisation = Normalisation.mission(scenario.mission.optimize)
    unit = np.random.default_rng(24).uniform(0.1, 0.9, size=(20, len(normalisation.names)))
    points = pd.DataFrame(normalisation.physical(unit), columns=list(normalisation.names))
    png = front_plot(directory / "front.png", normalisation, verified=points, title="UI test")
    started = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-c", PUBLISH, str(directory)],
        cwd=REPO,
        env=ui_server.env,
        capture_output=True,
        text=True,
        timeout=PUBLISH_TIMEOUT_S,
    )
    assert done.returncode == 0, f"the flow run failed:\n{done.stdout}\n{done.stderr}"
    print(f"\nflow run published in {time.monotonic() - started:.1f} s")
    with SyncPrefectClient(f"{ui_server.address}/api") as client:
        found = client.read_artifacts(
            artifact_filter=ArtifactFilter(key=ArtifactFilterKey(any_=list(KEYS)))
        )
    artifacts = {a.key: a for a in found}
    assert set(artifacts) == set(KEYS), sorted(artifacts)
    return Published(png=Path(png), artifacts=artifacts)


def _chromium(profile: Path, *args: str) -> str:
    """Run headless chromium (own profile, time-limited, its process group ended); stdout."""
    command = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",  # a container's small /dev/shm
        f"--user-data-dir={profile}",
        f"--virtual-time-budget={RENDER_BUDGET_MS}",
        *args,
    ]
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        out, err = process.communicate(timeout=CHROMIUM_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"chromium {args[-1]}: no result after {CHROMIUM_TIMEOUT_S:.0f} s")
    finally:
        _stop(process, signal.SIGKILL, timeout_s=10)  # and whatever it left in its group
    assert process.returncode == 0, f"chromium exited {process.returncode}:\n{err[-3000:]}"
    return out


def _page(server: UIServer, ui: str, artifact_id: Any) -> str:
    return f"{server.address}{UIS[ui]}/artifacts/artifact/{artifact_id}"


def test_the_markdown_embeds_each_png_with_its_path_as_caption(published):
    image = png_data_uri(published.png)
    for key, artifact in published.artifacts.items():
        assert artifact.type == "markdown"
        assert f"![front.png]({image})" in artifact.data, key
        assert f"`{published.png}`" in artifact.data, key
    assert "plan.json" in published.artifacts["mission-plan"].data


@pytest.mark.parametrize("ui", list(UIS))
def _embedded_pngs(dom: str) -> list[str]:
    """The ``src`` of every ``<img>`` of the DOM that is a PNG ``data:`` URI."""
    sources = re.findall(r'<img\b[^>]*?\ssrc="([^"]*)"', dom)
    return [s for s in sources if s.startswith("data:image/png;base64,")]


@pytest.mark.parametrize("ui", list(UIS))
def test_the_artifact_page_renders_the_embedded_png(ui_server, published, ui, tmp_path):
    """The UI at ``/`` (v1) parses the markdown in a web worker, which chromium's virtual
    time does not wait for: on a busy machine the DOM can be dumped before the worker's
    answer (seen once, with a 1 MB artifact), so an empty page is loaded again, 3 times
    at most; the PNG must be in the page."""
    image = png_data_uri(published.png)
    for key, artifact in published.artifacts.items():
        url = _page(ui_server, ui, artifact.id)
        for _ in range(DUMP_ATTEMPTS):
            dom = _chromium(tmp_path / "profile", "--dump-dom", url)
            embedded = _embedded_pngs(dom)
            if embedded:
                break
        where = f"{key} at {url}"
        assert embedded, (
            f"{where}: no <img> with a data:image/png;base64 src in {len(dom)} characters "
            f"of DOM ({DUMP_ATTEMPTS} loads):\n{dom[:2000]}"
        )
        assert image in embedded, f"{where}: the <img> is not front.png ({embedded[0][:80]}...)"
        assert str(published.png) in dom, f"{where}: no caption {published.png}"


def test_a_screenshot_of_the_artifact_page_shows_the_plot(ui_server, published, tmp_path):
    """The front plot's red points are painted in the default UI: ~310 pixels of their red
    here, none on the page when the markdown holds the path alone."""
    from matplotlib.image import imread

    shot = tmp_path / "page.png"
    url = _page(ui_server, "v2", published.artifacts["mission-plan"].id)
    _chromium(tmp_path / "profile", "--window-size=1280,1000", f"--screenshot={shot}", url)
    pixels = np.rint(imread(shot)[..., :3] * 255)
    red = int((np.abs(pixels - RED).max(axis=-1) < 40).sum())
    assert red > 100, f"{url}: {red} red pixels of the plot's points in {shot}"
