"""A candidate's fit asked for again (a screening pick that was an option already: the same terms, start and
bounds) is not fitted again: :meth:`Diagnoser._fit_converged` returns the first result, and a fit made in a
worker process of a batch (:meth:`_Picks._each`) is kept for later batches too.  The returned result is the one
a fresh fit gives, to the bit, and a copy (a caller that changes it does not change what a later one gets).

The worker check runs in a fresh interpreter (tests/fresh_process.py), as tests/updating/test_diagnosis_parallel.py
explains."""
from __future__ import annotations

import logging
import multiprocessing as mp
import time

import numpy as np
import pytest

from tests.fresh_process import Keep, run_fresh, workers_of


def _diagnoser(jobs: int):
    """The thesis beam (20 DOFs, cords of 100 N/m left out of the nominal) after steps 1-3, and a grounded
    spring at 1+Z added: ``(diagnoser, augmented model, lower, upper, two starts)``."""
    from tests.updating.test_diagnosis_beam import _measured
    from updating.diagnosis import Diagnoser, DiagnoserConfig
    from updating.diagnosis.library import build_library
    from updating.diagnosis.terms import _augmented
    from updating.fe.models.beams import thesis_beam, thesis_beam_parameters

    nominal = thesis_beam("analytical", cord_stiffness=None)
    params = thesis_beam_parameters(nominal)
    d = Diagnoser(DiagnoserConfig(parameters=params, priors={p.name: "free" for p in params}, jobs=jobs))
    d._t0, d.timings = time.perf_counter(), {}                     # as Diagnoser.fit starts
    d.baseline(nominal, _measured(100.0))
    d.localise()
    c = next(c for c in build_library(d.model0, kinds={"ground_spring"}) if c.dofs == ("1+Z",))
    pm, lo, hi, scales = _augmented(d.model0, d.params, d.lo, d.hi, [c])
    starts = [np.r_[d.upd.p, [v / scales[-1]]] for v in (50.0, 300.0)]
    return d, pm, lo, hi, starts


def _count_fits():
    """Count the FRF fits the diagnoser makes (the real fits, counted): ``(calls, restore)``."""
    import updating.diagnosis.workflow as wf
    calls = []
    real = wf.fit_frf
    wf.fit_frf = lambda *a, **k: calls.append(1) or real(*a, **k)
    return calls, lambda: setattr(wf, "fit_frf", real)


def test_the_same_fit_asked_again_is_the_first_result_not_a_new_fit():
    d, pm, lo, hi, (s0, _) = _diagnoser(jobs=1)
    calls, restore = _count_fits()
    try:
        first = d._fit_converged(pm, s0, lo, hi)
        n_first = len(calls)
        again = d._fit_converged(pm, s0.copy(), lo.copy(), hi.copy())
        assert n_first >= 1 and len(calls) == n_first              # no new fit
        again.p[:] = 0.0                                            # a copy: the kept result is untouched
        third = d._fit_converged(pm, s0, lo, hi)
        assert third.p.tobytes() == first.p.tobytes() and third.error == first.error
        p_first = first.p.copy()
        first.p[:] = 0.0                                            # nor does a change to the first result
        assert d._fit_converged(pm, s0, lo, hi).p.tobytes() == p_first.tobytes()
        first.p[:] = p_first
        other = d._fit_converged(pm, s0 * 1.001, lo, hi)            # another start is another fit
        assert len(calls) > n_first and other is not None
    finally:
        restore()
    d2, pm2, lo2, hi2, _ = _diagnoser(jobs=1)                       # a fresh fit, in a fresh diagnoser
    fresh = d2._fit_converged(pm2, s0, lo2, hi2)
    assert fresh.p.tobytes() == first.p.tobytes() and fresh.std.tobytes() == first.std.tobytes()
    assert fresh.error == first.error and fresh.message == first.message


def check_fits_of_workers_are_kept():
    kept = Keep()
    logging.getLogger().addHandler(kept.handler)
    logging.getLogger().setLevel(logging.DEBUG)
    d, pm, lo, hi, starts = _diagnoser(jobs=2)
    del kept[:]
    out = d._each(d._fit_converged, [(pm, s, lo, hi) for s in starts])
    assert workers_of(kept), "the batch's fits did not run in worker processes"
    calls, restore = _count_fits()
    try:
        again = [d._fit_converged(pm, s, lo, hi) for s in starts]
    finally:
        restore()
    assert not calls, "a fit made in a worker was made again"
    assert [a.p.tobytes() for a in again] == [o.p.tobytes() for o in out]


@pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="no fork start method here")
def test_fits_made_in_worker_processes_are_kept_for_later_batches():
    run_fresh("tests.updating.test_diagnosis_fit_memo", "check_fits_of_workers_are_kept")
