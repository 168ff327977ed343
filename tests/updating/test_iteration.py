"""The one iteration loop of the FRF-based updaters (updating.methods.iteration): bounds, step limit, line
search and the convergence test, on problems whose answer is known."""
import numpy as np
import pytest

from modalab.core.errors import ModalabValueError
from updating.methods.iteration import Proposal, default_bounds, iterate

TARGET = np.array([2.0, -3.0, 0.5])


def newton(p):
    """Exact Newton step on ½‖p − TARGET‖² (one step lands on the target)."""
    return Proposal(TARGET - p, float(np.sum((p - TARGET) ** 2)))


def rel(p, p_new):
    return np.ones_like(p)


def test_exact_step_converges_and_records_history():
    run = iterate(newton, np.zeros(3), np.arange(3), np.full(3, -10.0), np.full(3, 10.0), max_iter=5, tol=1e-12,
                  change_ref=rel)
    np.testing.assert_array_equal(run.p, TARGET)
    assert run.converged and run.n_iter == 2          # the second step is zero
    assert [h["iteration"] for h in run.history] == [1, 2]
    assert run.history[0]["cost"] == pytest.approx(np.sum(TARGET ** 2))
    np.testing.assert_array_equal(run.history[0]["p"], TARGET)


def test_only_the_updated_parameters_move_and_bounds_clip():
    run = iterate(lambda p: Proposal((TARGET - p)[:2], 0.0), np.zeros(3), [0, 1], np.array([-10.0, -1.0, -10.0]), np.full(3, 10.0), max_iter=3,
                  tol=1e-12, change_ref=rel)
    np.testing.assert_array_equal(run.p, [2.0, -1.0, 0.0])   # p[1] held at its lower bound, p[2] not updated


def test_step_limit_scales_the_whole_step():
    run = iterate(newton, np.ones(3), np.arange(3), np.full(3, -10.0), np.full(3, 10.0), max_iter=1, tol=0.0,
                  change_ref=rel, step_limit=0.5, step_ref=np.ones(3))
    dp = TARGET - 1.0
    np.testing.assert_allclose(run.p, 1.0 + dp * 0.5 / np.abs(dp).max())
    assert not run.converged and run.change == pytest.approx(0.5)


def test_line_search_halves_until_accepted():
    seen = []

    def propose(p):
        def accept(p_new):
            seen.append(p_new[0])
            return p_new[0] <= 1.0                       # accept only steps that do not overshoot 1
        return Proposal(np.array([8.0]), 0.0, accept)
    run = iterate(propose, np.zeros(1), [0], np.array([-np.inf]), np.array([np.inf]), max_iter=1, tol=0.0,
                  change_ref=rel)
    assert seen == [8.0, 4.0, 2.0, 1.0]
    assert run.p[0] == 1.0


def test_default_bounds_keep_sign_and_reject_crossed_bounds():
    lo, hi = default_bounds(None, np.array([2.0, -2.0, 0.0]))
    np.testing.assert_allclose(lo, [0.1, -40.0, 0.0])
    np.testing.assert_allclose(hi, [40.0, -0.1, np.inf])
    with pytest.raises(ModalabValueError, match="lower bounds exceed"):
        default_bounds((np.ones(2), np.zeros(2)), np.ones(2))
