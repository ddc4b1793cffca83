"""Work on a pool with this process as fallback (ovtraj.parallel)."""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from ovtraj.parallel import Bounded, mapped

RELEASE = threading.Event()


def _square_here(x: int) -> int:
    """x squared; in a pool's thread it waits (a cluster with no worker left) first."""
    if threading.current_thread() is not threading.main_thread():
        RELEASE.wait(30.0)
    return x * x


def test_work_the_pool_leaves_pending_past_its_bound_is_done_here(caplog):
    with ThreadPoolExecutor(2) as pool:
        started = time.monotonic()
        with caplog.at_level(logging.WARNING, logger="ovtraj.parallel"):
            values = mapped(_square_here, [(k,) for k in range(4)], Bounded(pool, 0.5))
        elapsed = time.monotonic() - started
        RELEASE.set()
    assert values == [0, 1, 4, 9]
    assert 0.5 <= elapsed < 10.0
    assert "the pool failed (TimeoutError)" in caplog.text
    assert "_square_here runs in this process" in caplog.text


def test_a_bounded_pool_that_answers_in_time_gives_its_results():
    with ThreadPoolExecutor(2) as pool:
        bounded = Bounded(pool, 30.0)
        assert list(bounded.map(pow, [2, 3], [2, 2])) == [4, 9]
        assert bounded.submit(pow, 2, 5).result() == 32
        bounded.shutdown()  # the owner's pool stays usable
        assert pool.submit(pow, 3, 3).result() == 27


def test_blas_threads_limits_every_blas_pool_and_restores_them():
    """The cached lookup limits the same pools threadpoolctl finds afresh."""
    from threadpoolctl import threadpool_info

    from ovtraj.parallel import blas_threads

    before = {p["filepath"]: p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}
    assert before  # numpy's and scipy's BLAS
    with blas_threads(1):
        inside = {
            p["filepath"]: p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"
        }
    after = {p["filepath"]: p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}
    assert set(inside) == set(before) and set(inside.values()) == {1}
    assert after == before
