"""Standard deviations of diagnosis fits: an undetermined parameter is not reported as exactly known."""
import json

import numpy as np
import pytest
import scipy.sparse as sp

from modalab.core.errors import ConvergenceError
from updating.diagnosis.fit import parameter_std
from updating.diagnosis.library import Candidate
from updating.diagnosis.findings import Finding


def test_parameter_std_full_rank_matches_the_covariance():
    rng = np.random.default_rng(3)
    J = rng.standard_normal((50, 3))
    std = parameter_std(J, 0.25)
    np.testing.assert_allclose(std, np.sqrt(np.diag(0.25 * np.linalg.inv(J.T @ J))), rtol=1e-10)


def test_parameter_std_undetermined_is_infinite_not_zero():
    """A parameter the data do not see, or two that only act together, have no finite standard deviation."""
    rng = np.random.default_rng(4)
    J = rng.standard_normal((40, 4))
    J[:, 1] = 0.0                                         # parameter 1 does not change the residual
    J[:, 3] = 2.0 * J[:, 2]                               # parameters 2 and 3 only act together
    std = parameter_std(J, 1.0)
    assert np.isinf(std[1]) and np.isinf(std[2]) and np.isinf(std[3])
    assert np.isfinite(std[0]) and std[0] > 0
    wide = parameter_std(rng.standard_normal((2, 3)), 1.0)  # fewer equations than parameters
    assert np.isinf(wide).any()


def test_parameter_std_non_finite_jacobian_fails_with_a_message():
    J = np.ones((10, 2))
    J[3, 1] = np.nan
    with pytest.raises(ConvergenceError, match=r"parameter\(s\) \[1\]"):
        parameter_std(J, 1.0)


def test_an_undetermined_value_is_written_as_null_not_infinity():
    c = Candidate("added_mass", "node 3", (3,), ("3+X", "3+Y", "3+Z"), (), "m", "kg", "M", True,
                  G=sp.identity(3, format="csr"))
    d = Finding(c, 0.2, float("inf"), "evidence", parts=[(c, 0.1, float("inf"))]).to_dict()
    assert d["values"][0]["std"] is None and d["parts"][0]["std"] is None
    json.dumps(d, allow_nan=False)                        # strict JSON: no Infinity
    assert Finding(c, 0.2, 0.01, "evidence").to_dict()["values"][0]["std"] == 0.01


def test_a_solution_from_outside_the_frf_fit_gets_the_frf_data_std_not_zero():
    """The workflow keeps the MCI solution when it fits the FRFs better than the joint FRF fit; its stated σ
    is then ``fit_std`` at that point (it was 0, a printed uncertainty no data support).  At an FRF fit's own
    solution ``fit_std`` gives that fit's σ back."""
    from pathlib import Path
    from modalab.core import uff
    from updating.fe import ParametricFEModel
    from updating.fe.bulk import build_model, read_bdf
    from updating.diagnosis.fit import fit_frf, fit_std, frf_data
    from updating.diagnosis.priors import default_parameters

    case = Path(__file__).resolve().parents[2] / "examples" / "concealed" / "bar_control"
    model = build_model(read_bdf(case / "nominal.bdf"))
    pm = ParametricFEModel(model, default_parameters(model))
    data = frf_data(uff.read_frf(case / "measured.uff"), max_lines=60)
    p0 = np.asarray(pm.p0, float)
    res = fit_frf(pm, data, p0, lower=0.5 * p0, upper=2 * p0, max_nfev=20)
    std = fit_std(pm, data, res.p)
    assert np.all(std > 0) and np.all(np.isfinite(std))
    np.testing.assert_allclose(std, res.std, rtol=0.05)


def test_parameter_std_does_not_depend_on_the_parameters_units():
    """Parameters in their own units differ by decades (a factor on E near 1, a clamp stiffness near 10⁶
    N·m/rad whose Jacobian column is ~10⁻⁸ as long): the stated σ of each follows its unit, and a short column
    is not cut as rank deficient (it was: the pseudo-inverse of the unscaled JᵀJ gave the stiffness
    σ ≈ 10⁻¹¹ N·m/rad on 2·10⁶)."""
    from updating.diagnosis.fit import correlated_std
    rng = np.random.default_rng(8)
    J = rng.standard_normal((60, 3))
    u = np.array([1.0, 1e-9, 1e4])                       # a parameter's unit made 10⁹ times larger: column / 10⁹
    meat = 0.3 * J.T @ J
    np.testing.assert_allclose(parameter_std(J * u, 0.5), parameter_std(J, 0.5) / u, rtol=1e-8)
    np.testing.assert_allclose(parameter_std(J * u, 0.5, meat=meat * np.outer(u, u)),
                               parameter_std(J, 0.5, meat=meat) / u, rtol=1e-8)
    r = 0.1 * rng.standard_normal(60)
    np.testing.assert_allclose(correlated_std(r, J * u, (1, 1, 30)), correlated_std(r, J, (1, 1, 30)) / u,
                               rtol=1e-6)
