"""A diagnosis on two processes (``jobs=2``: the independent fits of a step side by side,
modalab.core.parallel) is the diagnosis on one, to the bit: the same findings, values, fit blocks, decisions
and statement.  The thesis' 20-DOF beam with its two 100 N/m cords (tests/updating/test_diagnosis_beam.py).

The check runs in a fresh interpreter (tests/fresh_process.py): fork_map stays serial while other threads
run, and a pytest worker may hold threads other tests left; it asserts that fits did run on workers."""
from __future__ import annotations

import logging
import multiprocessing as mp

import pytest

from tests.fresh_process import Keep, run_fresh, workers_of


def check_two_processes():
    from tests.updating.test_diagnosis_beam import _measured
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
        d = diagnose(nominal, meas, parameters=params, priors={p.name: "free" for p in params}, jobs=jobs).to_dict()
        d.pop("timings_s")
        docs.append(d)
        workers.append(workers_of(kept))
    assert not workers[0] and workers[1], f"records from other processes: {workers}"
    assert docs[0]["findings"], "the cords are found (test_diagnosis_beam)"
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
