"""Which fitted picks have their neighbouring places fitted too (:meth:`_Picks._kind_bests`)."""
from __future__ import annotations

from types import SimpleNamespace

from updating.diagnosis.picks import _Picks


def _t(error: float, physics: str, value_name: str, label: str) -> tuple:
    return (error, SimpleNamespace(physics=physics, value_name=value_name, label=label))


def test_the_best_of_each_kind_that_lowered_the_error_best_first():
    tried = [_t(0.063, "added_mass", "J", "J@25"), _t(0.035, "added_mass", "m", "m@2"),
             _t(0.029, "ground_spring", "k", "k@12"), _t(0.042, "added_mass", "J", "J@4"),
             _t(0.053, "ground_spring", "k", "k@11")]
    assert [t[1].label for t in _Picks._kind_bests(tried, 0.0916)] == ["k@12", "m@2", "J@4"]


def test_kinds_that_did_not_lower_the_error_are_left_but_the_best_is_always_kept():
    tried = [_t(0.10, "added_mass", "m", "m@2"), _t(0.12, "ground_spring", "k", "k@12"),
             _t(0.05, "added_mass", "J", "J@4")]
    assert [t[1].label for t in _Picks._kind_bests(tried, 0.09)] == ["J@4"]
    assert [t[1].label for t in _Picks._kind_bests(tried[:2], 0.09)] == ["m@2"]
