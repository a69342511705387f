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


def test_full_collections_leave_their_survivors_out_and_everything_is_still_reclaimed(monkeypatch):
    """A full collection froze nothing and scanned every object of the window and its project
    (~160,000 at 1,000 points: 100–175 ms on the GUI thread about every hundred clicks). Its
    survivors are now frozen, and what they later leave in reference cycles is reclaimed by
    the full collection of everything the memory keeper and the tests run."""
    import gc
    import weakref

    from prismstation.gui import workers

    class Node:
        pass

    workers.collect_everything()
    a = Node()
    a.me = a                                                    # a reference cycle
    alive = weakref.ref(a)
    monkeypatch.setattr(gc, "get_count", lambda: (0, 0, 10**6))  # a full collection is due
    frozen = gc.get_freeze_count()
    workers.collect_if_due()
    assert gc.get_freeze_count() > frozen                       # its survivors, `a` among them
    del a
    gc.collect()
    assert alive() is not None                                  # left out of full collections
    workers.collect_everything()
    assert alive() is None                                      # reclaimed


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_the_memory_keeper_reclaims_cycles_made_before_a_freeze(qtbot):
    """The keeper's collection after a large job must reach what a freeze set aside while the
    job ran (its arrays in reference cycles)."""
    import gc
    import weakref

    keeper = MemoryKeeper(busy=lambda: False)
    keeper._timer.stop()

    class Holder:
        pass

    h = Holder()
    h.me, h.data = h, np.ones(6_000_000)                        # 48 MB in a cycle
    alive = weakref.ref(h)
    gc.freeze()                                                 # a full collection ran meanwhile
    del h
    keeper._floor = resident_mb() - 2 * keeper.STEP_MB          # as after a job's growth
    keeper.check()
    assert alive() is None and keeper.trims == 1
