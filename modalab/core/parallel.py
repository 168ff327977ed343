"""Independent calls on the machine's cores, with the results and the log in the order of a serial run.

``fork_map(fn, items, jobs)`` is ``[fn(*x) for x in items]``: with ``jobs`` > 1 computed by forked worker
processes (each sees the caller's state as it was at the call, and its changes to that state are lost: ``fn``
must return what it produces), the results in the order of ``items``.  Bit for bit the same results as the
serial loop: the same code runs on the same data, and nothing is reduced across processes.  The log records
a call makes in a worker are handed back and passed to the caller's handlers in the order of ``items``, as a
serial run would have passed them; progress printed directly (not through ``logging``) is not.

Results travel back pickled, except the objects given as ``by_reference`` (objects of the caller, e.g. ones
that hold local functions and cannot be pickled): a result that refers to one gets the caller's object itself.

Serial (in this process) when ``jobs`` is 1, when there are fewer than two items, where the ``fork`` start
method does not exist (Windows), while other threads run in this process (a fork copies the calling thread
alone, and a lock another thread holds would stay locked in the copy: a progress bar's refresh thread, a
threaded scheduler) and inside a worker process of :mod:`multiprocessing` or of
:mod:`concurrent.futures` (a campaign's, a Dask worker's, or this module's own): there the cores are already
shared out, and nested pools would oversubscribe them.  Layer 1: imports nothing of the project.
"""
from __future__ import annotations

import io
import logging
import multiprocessing as mp
import os
import pickle
import threading

__all__ = ["fork_map", "available_cores"]

_WORK = None          # (fn, items, {id: object} passed by reference) of the running fork_map, read by the workers


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform says, else ``os.cpu_count``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:                     # not on every platform (macOS, Windows)
        return max(1, os.cpu_count() or 1)


def _serial(jobs: int, n: int) -> bool:
    return (jobs <= 1 or n < 2 or "fork" not in mp.get_all_start_methods()
            or mp.parent_process() is not None or threading.active_count() > 1)


def fork_map(fn, items, jobs: int | None = None, by_reference=()) -> list:
    """``[fn(*x) for x in items]``, on ``jobs`` processes (None: :func:`available_cores`); see the module."""
    global _WORK
    items = [tuple(x) for x in items]
    jobs = available_cores() if jobs is None else int(jobs)
    if jobs < 1:
        raise ValueError(f"jobs = {jobs}: expected a positive number of processes")
    if _serial(jobs, len(items)):
        return [fn(*x) for x in items]
    refs = {id(o): o for o in by_reference}
    _WORK = (fn, items, refs)
    try:
        with mp.get_context("fork").Pool(min(jobs, len(items))) as pool:
            out = pool.map(_worker, range(len(items)), chunksize=1)
    finally:
        _WORK = None
    results = []
    for blob in out:
        loader = pickle.Unpickler(io.BytesIO(blob))
        loader.persistent_load = refs.__getitem__
        result, records = loader.load()
        for name, record in records:
            logging.getLogger(name or None).callHandlers(record)
        results.append(result)
    return results


def _worker(i: int):
    """Item ``i`` of the running :func:`fork_map` in a worker: ``(result, [(logger name, record)])`` pickled
    (the objects passed by reference as their ids), the records those the call's loggers would have passed to
    their handlers (levels and filters applied)."""
    fn, items, refs = _WORK
    records = []

    def keep(logger, record):
        record.msg, record.args = record.getMessage(), None        # the arguments may not pickle
        if record.exc_info:
            record.exc_text = logging.Formatter().formatException(record.exc_info)
            record.exc_info = None
        records.append((logger.name if logger is not logging.root else "", record))

    saved = logging.Logger.callHandlers
    logging.Logger.callHandlers = keep
    try:
        out = fn(*items[i]), records
    finally:
        logging.Logger.callHandlers = saved
    buf = io.BytesIO()
    dumper = pickle.Pickler(buf, pickle.HIGHEST_PROTOCOL)
    dumper.persistent_id = lambda o: id(o) if id(o) in refs and refs[id(o)] is o else None
    dumper.dump(out)
    return buf.getvalue()
