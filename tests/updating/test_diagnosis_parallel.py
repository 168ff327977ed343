"""A diagnosis on two processes (``jobs=2``: the independent fits of a step side by side,
modalab.core.parallel) is the diagnosis on one, to the bit: the same findings, values, fit blocks, decisions
and statement.  The thesis' 20-DOF beam with its two 100 N/m cords (tests/updating/test_diagnosis_beam.py),
whose findings it checks as that module checks the 1000 N/m ones (the diagnosis is run once for both).

The check runs in a fresh interpreter (tests/fresh_process.py): fork_map stays serial while other threads
run, and a pytest worker may hold threads other tests left; it asserts that fits did run on workers."""
from __future__ import annotations

import logging
import multiprocessing as mp

import pytest

from tests.fresh_process import Keep, run_fresh, workers_of


def check_two_processes():
    from tests.updating.test_diagnosis_beam import _measured, assert_cords_named
    from updating.diagnosis import diagnose
    from updating.fe.models.beams import thesis_beam, thesis_beam_parameters

    kept = Keep()
    logging.getLogger().addHandler(kept.handler)
    logging.getLogger().setLevel(logging.DEBUG)
    nominal = thesis_beam("analytical", cord_stiffness=None)
    meas = _measured(100.0)
    params = thesis_beam_parameters(nominal)
    docs, workers = [], []
    for jobs in (1, 2):
        del kept[:]
        diag = diagnose(nominal, meas, parameters=params, priors={p.name: "free" for p in params}, jobs=jobs)
        if jobs == 1:
            assert_cords_named(diag, meas, 100.0)       # test_diagnosis_beam's check of the 100 N/m cords
        d = diag.to_dict()
        d.pop("timings_s")
        docs.append(d)
        workers.append(workers_of(kept))
    assert not workers[0] and workers[1], f"records from other processes: {workers}"
    assert docs[0] == docs[1]


@pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="no fork start method here")
def test_two_processes_give_the_diagnosis_of_one():
    run_fresh("tests.updating.test_diagnosis_parallel", "check_two_processes")


def test_jobs_is_a_positive_number_of_processes():
    from modalab.core.errors import ModalabValueError
    from updating.diagnosis import DiagnoserConfig
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ModalabValueError, match="jobs="):
            DiagnoserConfig(jobs=bad)
