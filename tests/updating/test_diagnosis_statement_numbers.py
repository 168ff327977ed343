"""The diagnosis statement's percentages (issue 14 audit): two significant digits, no exponent, a nonzero value
never printed as 0 and a change that rounds away called unchanged (the README chain read "from 1.0 % to 1.0 %"
for 0.961 % -> 0.951 %; the modes-only statement printed '0.0 %' for a nonzero error, or many digits)."""
import pytest

from updating.diagnosis.findings import from_to, pct, statement


@pytest.mark.parametrize("x, text", [(0.0, "0"), (0.004, "0.004"), (4e-5, "0.00004"), (0.3, "0.3"), (0.9514, "0.95"),
                                     (4.14, "4.1"), (2.962, "3.0"), (9.96, "10"), (38.2, "38"), (120.4, "120")])
def test_percentages_print_with_two_significant_digits(x, text):
    assert pct(x) == text


def _fit(nom, par, phys):
    return {"nominal": {"frf_error_held_out": nom}, "parameters_only": {"frf_error_held_out": par},
            "with_physics": {"frf_error_held_out": phys}}


def test_a_small_change_shows_and_no_change_is_called_unchanged():
    s = statement([], _fit(0.009612, 0.009514, 0.009514), "response DOFs 4+Z")
    assert "from 0.96 % to 0.95 %" in s and "from 1.0 % to 1.0 %" not in s, s
    s = statement([], _fit(0.003001, 0.002999, 0.002999), "response DOFs 4+Z")
    assert "leaves the held-out FRF error (response DOFs 4+Z) unchanged at 0.3 %" in s, s
    assert from_to(0.00004, 0.0) == "from 0.00004 % to 0 %"


def test_the_evidence_never_says_zero_percent_for_a_nonzero_share():
    from types import SimpleNamespace

    from updating.diagnosis.terms import _evidence

    c = SimpleNamespace(matrix="K", dofs=["3+Z"], nodes=[3], physics="ground_spring")
    o = SimpleNamespace(physics="added_mass", label="point mass at node 3")
    s = _evidence(c, 0.003, [(o, None, 0.0004)], (5.0, 700.0))
    assert "explains 0.3 % of the residual" in s and "added mass there explains 0.04 %" in s, s
    assert " 0 %" not in s


def test_no_finding_with_held_out_frfs_above_their_noise_is_no_evidence_of_completeness():
    """Tuning case 2154 (a 44 g mass on a planar frame's brace, never ranked): nothing was found and the statement
    said "Nothing is missing beyond parameter error" while the parameters-only fit left the held-out FRFs at
    χ²/N 16.6.  Above the noise limit the statement now says what the data show: nothing the library can name,
    and something left out; at the noise, and with a finding, it is unchanged."""
    fit = _fit(0.27, 0.10, 0.10)
    fit["parameters_only"]["chi2_per_value_held_out"] = 16.6
    s = statement([], fit, "response DOFs 11+Z", noise_limit=1.5)
    assert "Nothing is missing that the candidate library can name" in s and "beyond parameter error" not in s, s
    assert "χ²/N 16.6" in s and "no evidence that the model is complete" in s, s
    fit["parameters_only"]["chi2_per_value_held_out"] = 0.9
    s = statement([], fit, "response DOFs 11+Z", noise_limit=1.5)
    assert "Nothing is missing beyond parameter error" in s and "no evidence" not in s, s
    fit["parameters_only"]["chi2_per_value_held_out"] = 16.6
    assert "no evidence" not in statement([], fit, "response DOFs 11+Z"), "the modes-only route passes no limit"
