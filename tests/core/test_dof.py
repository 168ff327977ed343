"""DOF labels: parsing, printing, UFF codes, signs."""
import pytest
from hypothesis import given, strategies as st

from modalab.core.dof import Dof, locate, parse_dofs
from modalab.core.errors import DofError, ModalabError


class TestParse:
    @pytest.mark.parametrize("text,node,code", [
        ("12+Z", 12, 3), ("12-Z", 12, -3), ("7+RX", 7, 4), ("7-ry", 7, -5), ("3", 3, 0),
        ("101+X", 101, 1), (" 5 - rz ", 5, -6), ("4+2", 4, 2)])
    def test_labels(self, text, node, code):
        d = Dof.parse(text)
        assert (d.node, d.direction) == (node, code)

    @pytest.mark.parametrize("bad", ["", "Z+12", "12+W", "12+7", "-3+Z", "12++Z", "abc"])
    def test_bad_labels_raise_clear_error(self, bad):
        with pytest.raises(DofError, match="expected a node id"):
            Dof.parse(bad)

    def test_error_is_value_error_and_modalab_error(self):
        with pytest.raises(ValueError):
            Dof.parse("x")
        with pytest.raises(ModalabError):
            Dof(1, 9)

    def test_tuple_and_dof_passthrough(self):
        assert Dof.parse((3, -2)) == Dof(3, -2)
        d = Dof(1, 1)
        assert Dof.parse(d) is d


@given(st.integers(0, 10**7), st.sampled_from([-6, -5, -4, -3, -2, -1, 0, 1, 2, 3, 4, 5, 6]))
def test_label_roundtrip(node, code):
    d = Dof(node, code)
    assert Dof.parse(str(d)) == d
    assert d.uff_code == code
    assert (-d).sign == (-1 if code > 0 else 1)
    assert hash(Dof.parse(str(d))) == hash(d)


def test_locate_signs_and_missing():
    dofs = parse_dofs(["1+Z", "2+Z", "3-Y"])
    idx, sgn = locate(dofs, ["2-Z", "3+Y", "1+Z"])
    assert idx == [1, 2, 0] and sgn == [-1, -1, 1]
    with pytest.raises(DofError, match="4\\+Z is not in the data"):
        locate(dofs, ["4+Z"])
    with pytest.raises(DofError, match="point DOF 4\\+Z is not in the model"):
        locate(dofs, ["4+Z"], "point DOF", "the model")
