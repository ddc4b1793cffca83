"""Work on a pool with this process as fallback (ovtraj.parallel)."""

from __future__ import annotations

import logging
import os
import threading
import time
from concurrent.futures import BrokenExecutor, ThreadPoolExecutor

import pytest

from ovtraj.parallel import Bounded, mapped, started

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


def test_work_started_early_is_collected_in_order_or_done_here_past_the_bound(caplog):
    with ThreadPoolExecutor(2) as pool:
        collect = started(pow, [(2, k) for k in range(5)], pool)
        assert collect() == [1, 2, 4, 8, 16]
    computed = []

    def noted(x: int) -> int:
        computed.append(x)
        return -x

    collect = started(noted, [(1,), (2,)], None)
    assert computed == []  # no executor: computed when collected
    assert collect() == [-1, -2] and computed == [1, 2]
    RELEASE.clear()
    with ThreadPoolExecutor(2) as pool:
        collect = started(_square_here, [(k,) for k in range(3)], Bounded(pool, 0.5))
        start = time.monotonic()
        with caplog.at_level(logging.WARNING, logger="ovtraj.parallel"):
            values = collect()
        elapsed = time.monotonic() - start
        RELEASE.set()
    assert values == [0, 1, 4]
    assert 0.5 <= elapsed < 10.0
    assert "the pool failed (TimeoutError" in caplog.text


def test_work_started_on_a_broken_pool_is_done_here(caplog):
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1) as pool:
        with pytest.raises(BrokenExecutor):
            pool.submit(os._exit, 3).result()  # its worker dies: the pool is broken
        with caplog.at_level(logging.WARNING, logger="ovtraj.parallel"):
            assert started(pow, [(3, 2), (2, 3)], pool)() == [9, 8]
    assert "the pool failed (BrokenProcessPool" in caplog.text
    assert "pow runs in this process" in caplog.text


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
