"""The window's memory: one Dask pool whatever thread computes, and the heap's free memory
handed back after large work (the figures are benchmarks/bench_memory.py's)."""
from __future__ import annotations

import sys
import threading

import numpy as np
import pytest

from prismstation.gui.memory import MemoryKeeper, one_dask_pool, resident_mb


def test_dask_computations_from_new_threads_share_one_pool():
    """Each tool job runs in a thread of its own; Dask made a pool per calling thread and kept
    it, with its threads' memory (a DSM of the demo: +50 to +125 MB per run)."""
    import dask

    one_dask_pool()
    pool = dask.config.get("pool")
    one_dask_pool()
    assert dask.config.get("pool") is pool                     # made once

    def compute():
        tasks = [dask.delayed(np.sum)(np.full(1000, k)) for k in range(8)]
        assert sum(dask.compute(*tasks, scheduler="threads")) == 1000 * sum(range(8))

    counts = []
    for _ in range(4):                                          # as four tool jobs
        t = threading.Thread(target=compute)
        t.start()
        t.join()
        counts.append(threading.active_count())
    assert len(set(counts)) == 1, counts                        # no pool left behind per job


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_memory_freed_by_a_worker_is_handed_back(qtbot):
    keeper = MemoryKeeper(busy=lambda: False)
    keeper._timer.stop()                                        # checked here, not by its timer
    keeper.check()
    before = resident_mb()

    kept = []

    def work():  # many mid-sized arrays: in a thread's heap, not mapped one by one
        arrays = [np.ones(12_000) for _ in range(2500)]        # 240 MB
        kept.extend(arrays[::25])                               # 10 MB left, spread over it all

    t = threading.Thread(target=work)
    t.start()
    t.join()
    grown = resident_mb()
    assert grown > before + 100, (before, grown)                # glibc kept what was freed
    keeper.check()
    assert keeper.trims >= 1 and resident_mb() < before + 60, (before, grown, resident_mb())
    del kept
