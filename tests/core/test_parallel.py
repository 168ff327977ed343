"""modalab.core.parallel.fork_map: the results and the log of a serial loop, computed by forked workers.

The checks that need the calls to go to forked workers run in a fresh interpreter (tests/fresh_process.py):
fork_map stays serial while other threads run, and a pytest worker may hold threads other tests left."""
import logging
import multiprocessing as mp
import os
import threading

import numpy as np
import pytest

from modalab.core.parallel import available_cores, fork_map
from tests.fresh_process import Keep, run_fresh, workers_of

_HERE = "tests.core.test_parallel"         # the name a fresh interpreter imports this file by
log = logging.getLogger("modalab.test.parallel")

needs_fork = pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="no fork start method here")


class Unpicklable:
    """Holds a local function, as a diagnosis candidate does: it cannot travel back pickled."""

    def __init__(self, k):
        self.k = k
        self.f = lambda x: x + k


def _work(obj, x):
    log.info("item %d in process %d", obj.k, os.getpid())
    return obj, obj.f(x), np.linalg.solve(np.eye(3) * (obj.k + 1), np.arange(3.0)), os.getpid()


def _fresh_clean():
    assert threading.active_count() == 1 and mp.parent_process() is None, "the process is not a fresh one"


def check_results_and_log():
    _fresh_clean()
    objs = [Unpicklable(k) for k in range(5)]
    items = [(o, 10 * o.k) for o in objs]
    kept = Keep()
    log.addHandler(kept.handler)
    log.setLevel(logging.INFO)
    par = fork_map(_work, items, 2, by_reference=objs)
    logged = [r.getMessage().split(" in ")[0] for r in kept]
    assert workers_of(kept), "the records come from the workers"
    del kept[:]
    ser = fork_map(_work, items, 1)
    assert not workers_of(kept)
    assert logged == [f"item {k}" for k in range(5)]            # in the order of the items, once each
    assert all(a[0] is o and b[0] is o for a, b, o in zip(par, ser, objs))      # the caller's own objects
    assert [a[1] for a in par] == [b[1] for b in ser] == [11 * k for k in range(5)]
    assert all(np.array_equal(a[2], b[2]) for a, b in zip(par, ser))
    assert {a[3] for a in par} - {os.getpid()}                  # computed elsewhere
    assert {b[3] for b in ser} == {os.getpid()}


@needs_fork
def test_results_and_log_are_those_of_the_serial_loop():
    run_fresh(_HERE, "check_results_and_log")


def _boom(k):
    if k == 2:
        raise ValueError(f"item {k} failed")
    return k


def check_failing_call():
    _fresh_clean()
    with pytest.raises(ValueError, match="item 2 failed"):
        fork_map(_boom, [(k,) for k in range(4)], 2)


@needs_fork
def test_a_failing_call_fails_the_map_with_its_own_error():
    run_fresh(_HERE, "check_failing_call")


def _nested(k):
    return fork_map(os.getpid, [(), ()], 2), os.getpid()


def check_nested():
    _fresh_clean()
    out = fork_map(_nested, [(0,), (1,)], 2)
    assert {pid for _, pid in out} - {os.getpid()}, "the outer map ran on workers"
    for inner, pid in out:
        assert inner == [pid, pid]


@needs_fork
def test_a_worker_runs_a_nested_map_in_its_own_process():
    run_fresh(_HERE, "check_nested")


def test_jobs_must_be_positive():
    with pytest.raises(ValueError, match="jobs = 0"):
        fork_map(_boom, [(0,)], 0)
    assert available_cores() >= 1


def check_unpicklable_result():
    _fresh_clean()
    with pytest.raises(Exception, match="pickle"):
        fork_map(_work, [(Unpicklable(k), 0) for k in range(2)], 2)


@needs_fork
def test_an_unpicklable_result_not_passed_by_reference_is_an_error_not_a_wrong_result():
    run_fresh(_HERE, "check_unpicklable_result")


def test_while_another_thread_runs_the_calls_stay_in_this_process():
    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    try:
        assert fork_map(os.getpid, [(), ()], 2) == [os.getpid()] * 2
    finally:
        stop.set()
        t.join()
