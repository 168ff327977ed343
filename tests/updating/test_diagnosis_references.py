"""Diagnosis with several fixed accelerometers, every one of them also hit (issue 13, failure 6).

The FRFs are stored as accelerometers x hammer points (5 x 10): no response row is free of a driving
point, which once left the held-out part empty and crashed ``model_frf`` with a float index array.
"""
from __future__ import annotations

import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF
from updating.diagnosis import Diagnoser, DiagnoserConfig, diagnose, frf_data
from updating.diagnosis.priors import _split
from updating.fe.models.beams import thesis_beam, thesis_beam_parameters


def _five_accelerometers():
    truth = thesis_beam("analytical", cord_stiffness=None)
    truth.global_ge = 0.02
    f = np.linspace(0.5, 200.0, 200)
    H = truth.frf(f, [f"{i}+Z" for i in (1, 3, 5, 7, 9)], [f"{i}+Z" for i in range(1, 11)],
                  quantity="receptance")
    return FRF(freq_hz=f, H=H.H, responses=H.responses, references=H.references, coherence=np.ones(H.H.shape),
               quantity="receptance")


def test_split_holds_out_references_when_every_response_is_a_driving_point():
    data = frf_data(_five_accelerometers(), max_lines=40)
    train, held, desc = _split(data, None)
    assert held.H.shape[0] == 5 and held.H.shape[1] >= 1 and train.H.shape[1] >= 1
    assert held.H.shape[1] + train.H.shape[1] == 10
    assert not {str(r) for r in held.references} & {str(r) for r in train.references}
    assert desc.startswith("reference")
    with pytest.raises(ModalabValueError, match="rows"):
        _split(data, "rows")


def test_an_empty_subset_is_refused():
    data = frf_data(_five_accelerometers(), max_lines=40)
    with pytest.raises(ModalabValueError, match="empty"):
        data.take(rows=np.array([], int))


def test_five_fixed_accelerometers_as_references_diagnose_without_crash():
    nominal = thesis_beam("analytical", cord_stiffness=None)
    est = Diagnoser(DiagnoserConfig(parameters=thesis_beam_parameters(nominal), max_lines=60, max_findings=1))
    assert est.fit(nominal, _five_accelerometers()) is est
    assert est.findings_ == [] and est.ranking_ and est.fit_ is est.diagnosis_.fit
    assert est.fit_["nominal"]["frf_error_held_out"] < 1e-6
    assert est.diagnosis_.steps["held_out"].startswith("reference")


def test_the_configuration_is_validated():
    with pytest.raises(ModalabValueError, match="did you mean 'added_mass'"):
        DiagnoserConfig(kinds=["added_mas"])
    with pytest.raises(ModalabValueError, match="criterion"):
        DiagnoserConfig(criterion="both")
    with pytest.raises(TypeError):
        diagnose(None, None, max_lnes=3)


def test_the_held_out_rows_leave_every_measured_direction_in_training():
    """A planar frame hit ten times, once out of plane (tuning case 1710's layout): every fourth row would hold out
    the only Z row, leaving the training FRFs blind to out-of-plane motion; it stays in training and the next
    candidate row is held out instead.  Where every direction keeps a training row, the rows are every fourth."""
    from modalab.core.dof import Dof
    from updating.diagnosis.priors import _held_rows

    rows = [Dof.parse(x) for x in ("8+Y", "1+Y", "15-Y", "5-X", "9+Y", "4+Z", "12+Y", "3+Y", "13+Y", "7+Y")]
    cand = list(range(10))
    held = _held_rows(rows, cand)
    assert [str(rows[i]) for i in held] == ["8+Y", "1+Y", "7+Y"]
    assert len(held) == len(cand[1::4])
    rows[4] = Dof.parse("9+Z")                     # a second Z row: the usual every fourth is kept
    assert _held_rows(rows, cand) == cand[1::4]
    rows = [Dof.parse(x) for x in ("1+Z", "2+Z", "3+Z", "4+Z", "5+Z")]
    assert _held_rows(rows, list(range(5))) == [1]
