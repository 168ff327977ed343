"""Parameters with priors (issue 13): defaults, overrides, the MAP fit, and how findings report
ambiguity and refinements."""
from __future__ import annotations

import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF
from updating.diagnosis import build_library, fit_frf, frf_data
from updating.diagnosis.fit import Prior
from updating.diagnosis.priors import parameter_priors
from updating.diagnosis.findings import Finding, _describe
from updating.fe import Parameter, ParametricFEModel
from updating.fe.models.beams import thesis_beam


def _params():
    return [Parameter("E_a", "E", properties=(1,)), Parameter("rho_a", "rho", properties=(1,)),
            Parameter("t_a", "h", properties=(1,)), Parameter("eta", "global_ge", mode="value")]


def test_default_priors_and_overrides():
    mean, sig = parameter_priors(_params(), [1.0, 1.0, 1.0, 0.02])
    np.testing.assert_allclose(mean, [1.0, 1.0, 1.0, 0.02])
    assert sig[0] == pytest.approx(0.05) and sig[1] == pytest.approx(0.03) and sig[2] == pytest.approx(0.05)
    assert np.isinf(sig[3])                                  # damping is free
    _, sig = parameter_priors(_params(), [1.0, 1.0, 1.0, 0.02], {"E_a": 0.2, "rho_a": "free", "eta": 0.5})
    assert sig[0] == pytest.approx(0.2) and np.isinf(sig[1]) and sig[3] == pytest.approx(0.01)
    with pytest.raises(ModalabValueError, match="did you mean 'E_a'"):
        parameter_priors(_params(), [1.0, 1.0, 1.0, 0.02], {"E_aa": 0.1})
    with pytest.raises(ModalabValueError, match="expected a relative standard deviation"):
        parameter_priors(_params(), [1.0, 1.0, 1.0, 0.02], {"E_a": -1})


def test_the_map_fit_is_pulled_to_the_prior_mean_by_its_weight():
    nominal = thesis_beam("analytical", cord_stiffness=None)
    truth = thesis_beam("analytical", cord_stiffness=None)
    nominal.global_ge = truth.global_ge = 0.05
    pm_t = ParametricFEModel(truth, [Parameter("E", "E", materials=tuple(truth.materials))])
    st = pm_t.structure([1.04])
    f = np.linspace(2.0, 150.0, 120)
    dofs = [f"{i}+Z" for i in range(1, 11)]
    H = st.frf(f, dofs, ["1+Z"], quantity="receptance")
    meas = FRF(freq_hz=f, H=H.H, responses=H.responses, references=H.references, coherence=np.ones(H.H.shape),
               quantity="receptance")
    data = frf_data(meas, max_lines=120)
    pm = ParametricFEModel(nominal, [Parameter("E", "E", materials=tuple(nominal.materials))])
    free = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0])
    assert free.p[0] == pytest.approx(1.04, abs=1e-3)
    weak = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0], prior=Prior(np.array([1.0]), np.array([0.05]), 1e-6))
    assert weak.p[0] == pytest.approx(1.04, abs=1e-3)           # a negligible prior weight changes nothing
    strong = fit_frf(pm, data, [1.0], lower=[0.5], upper=[2.0], prior=Prior(np.array([1.0]), np.array([0.05]), 1e3))
    assert abs(strong.p[0] - 1.0) < 0.5 * abs(free.p[0] - 1.0)  # a heavy prior holds the parameter back
    assert strong.error > free.error


def _beam_cands():
    m = thesis_beam("analytical", cord_stiffness=None)
    lib = build_library(m, kinds=["added_mass", "ground_spring"])
    a = next(c for c in lib if c.physics == "added_mass" and c.nodes == (7,) and c.value_name == "m")
    b = next(c for c in lib if c.physics == "ground_spring" and c.dofs == ("3+Z",))
    return a, b


def test_an_ambiguous_finding_names_both_explanations():
    a, b = _beam_cands()
    f = Finding(a, 0.12, 0.01, "because", alternatives=[(b, 3000.0)])
    d = f.to_dict()
    assert d["ambiguous"] is True and d["alternatives"][0]["dofs"] == ["3+Z"]
    assert d["alternatives"][0]["value"] == 3000.0 and " or " in d["description"]
    text = _describe(f)
    assert text.startswith("either ") and "cannot tell them apart" in text and "3e+03 N/m" in text


def test_a_plain_finding_is_not_ambiguous():
    a, _ = _beam_cands()
    d = Finding(a, 0.12, 0.01, "because").to_dict()
    assert d["ambiguous"] is False and d["alternatives"] == [] and d["parts"] == [] and " or " not in d["description"]


def test_priors_from_the_parameter_file(tmp_path):
    from updating.fe.parameter_file import read_priors as _priors
    from modalab.core.errors import PlanError
    f = tmp_path / "p.toml"
    f.write_text('[[parameter]]\nname = "E_a"\nfield = "E"\nproperties = ["a"]\nprior = 0.2\n\n'
                 '[[parameter]]\nname = "rho_a"\nfield = "rho"\nproperties = ["a"]\nprior = "free"\n\n'
                 '[[parameter]]\nname = "h_a"\nfield = "h"\nproperties = ["a"]\n')
    assert _priors(f) == {"E_a": 0.2, "rho_a": "free"}
    f.write_text('[[parameter]]\nname = "E_a"\nfield = "E"\nproperties = ["a"]\nprior = -3\n')
    with pytest.raises(PlanError, match="E_a.*prior = -3"):
        _priors(f)


def test_a_zero_nominal_value_has_no_relative_prior():
    params = [Parameter("di", "di", properties=(1,), mode="value")]
    _, sig = parameter_priors(params, [0.0])
    assert np.isinf(sig[0])


def test_other_physics_at_the_same_node_is_another_explanation():
    """Two kinds at one node (a spring or an inertia there) are two explanations, reported as one ambiguous
    finding when both fit; the same kind one node over is a localisation spread, not a second explanation."""
    from updating.diagnosis.terms import _another_explanation
    m = thesis_beam("analytical", cord_stiffness=None)
    lib = build_library(m, kinds=["added_mass", "ground_spring"])
    mass7 = next(c for c in lib if c.physics == "added_mass" and c.nodes == (7,) and c.value_name == "m")
    spring7 = next(c for c in lib if c.physics == "ground_spring" and c.dofs == ("7+Z",))
    spring8 = next(c for c in lib if c.physics == "ground_spring" and c.dofs == ("8+Z",))
    spring3 = next(c for c in lib if c.physics == "ground_spring" and c.dofs == ("3+Z",))
    assert _another_explanation(spring7, mass7, m) and _another_explanation(mass7, spring7, m)
    assert not _another_explanation(spring8, spring7, m)        # the neighbour: the same explanation, spread
    assert _another_explanation(spring3, spring7, m)            # elsewhere
