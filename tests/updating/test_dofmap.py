"""Mapping test DOF labels onto model DOFs: node numbers, explicit maps, signs, frames, oblique sensors."""
import numpy as np
import pytest

from modalab.core.errors import DofError, ModalabValueError, ShapeError
from modalab.core.modes import ModeSet
from updating.correlation.dofmap import DofMap, as_dofmap, observation_matrix

MODEL = [f"{n}+{d}" for n in (12, 13, 14) for d in ("X", "Y", "Z", "RX", "RY", "RZ")]


def dense(C):
    return np.asarray(C.toarray())


def row(label):
    """Unit row over MODEL for one model label."""
    r = np.zeros(len(MODEL))
    r[MODEL.index(label)] = 1.0
    return r


class TestSameNodes:
    def test_identity_selection(self):
        C = dense(DofMap().matrix(["12+Z", "14+RX"], MODEL))
        np.testing.assert_array_equal(C, np.vstack([row("12+Z"), row("14+RX")]))

    def test_negative_test_label_negates(self):
        C = dense(observation_matrix(["13-Y"], MODEL))
        np.testing.assert_array_equal(C, -row("13+Y")[None])

    def test_negative_model_label_negates(self):
        model = ["12+X", "12-Z"]
        np.testing.assert_array_equal(dense(DofMap().matrix(["12+Z"], model)), [[0.0, -1.0]])

    def test_unmapped_dofs_are_all_named(self):
        with pytest.raises(DofError) as e:
            DofMap().matrix(["12+Z", "99+Z", "98+X"], MODEL)
        msg = str(e.value)
        assert "99+Z" in msg and "98+X" in msg and "2 test DOF" in msg and "map" in msg

    def test_same_nodes_off(self):
        with pytest.raises(DofError, match="same_nodes"):
            DofMap(same_nodes=False).matrix(["12+Z"], MODEL)

    def test_scalar_test_dof_rejected(self):
        with pytest.raises(DofError, match="direction"):
            DofMap().matrix(["12"], MODEL)


class TestExplicitMap:
    def test_dof_and_node_entries(self):
        dm = DofMap(dofs={"101+Z": "12-Z", "102+X": {"13+X": 0.6, "13+Y": 0.8}}, nodes={103: 14})
        C = dense(dm.matrix(["101+Z", "102+X", "103+Y", "101-Z"], MODEL))
        np.testing.assert_allclose(C[0], -row("12+Z"))
        np.testing.assert_allclose(C[1], 0.6 * row("13+X") + 0.8 * row("13+Y"))
        np.testing.assert_allclose(C[2], row("14+Y"))
        np.testing.assert_allclose(C[3], row("12+Z"))         # 101-Z = -(101+Z) = +12+Z

    def test_negative_entry_key(self):
        dm = DofMap(dofs={"101-Z": "12+Z"})
        np.testing.assert_allclose(dense(dm.matrix(["101+Z"], MODEL))[0], -row("12+Z"))

    def test_duplicate_entry(self):
        with pytest.raises(ModalabValueError, match="twice"):
            DofMap(dofs={"101+Z": "12+Z", "101-Z": "13+Z"})

    def test_direction_vector_entry(self):
        dm = DofMap(dofs={"201+X": {"node": 13, "direction": [0.0, 3.0, 4.0]}})
        C = dense(dm.matrix(["201+X"], MODEL))
        np.testing.assert_allclose(C[0], 0.6 * row("13+Y") + 0.8 * row("13+Z"))

    def test_bad_direction(self):
        with pytest.raises(ModalabValueError, match="non-zero 3-vector"):
            DofMap(dofs={"201+X": {"node": 13, "direction": [0.0, 0.0]}})


class TestFrames:
    # test node 12 rotated +90° about Z: local x = global Y, local y = -global X
    RZ90 = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]

    def test_test_frame_rotates_direction(self):
        dm = DofMap(test_frames={12: self.RZ90})
        C = dense(dm.matrix(["12+X", "12+Y", "12+RY"], MODEL))
        np.testing.assert_allclose(C[0], row("12+Y"), atol=1e-15)
        np.testing.assert_allclose(C[1], -row("12+X"), atol=1e-15)
        np.testing.assert_allclose(C[2], -row("12+RX"), atol=1e-15)

    def test_model_frame_uses_transpose(self):
        # model node 13 displacement system rotated +90° about Z: a global-Y sensor reads the local x DOF
        dm = DofMap(model_frames={13: self.RZ90})
        C = dense(dm.matrix(["13+Y"], MODEL))
        np.testing.assert_allclose(C[0], row("13+X"), atol=1e-15)

    def test_same_frame_on_both_sides_cancels(self):
        rng = np.random.default_rng(0)
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        dm = DofMap(test_frames={14: Q}, model_frames={14: Q})
        C = dense(dm.matrix(["14+X", "14+Y", "14+Z"], MODEL))
        np.testing.assert_allclose(C[:, 12:15], np.eye(3), atol=1e-12)

    def test_oblique_projection_of_modes(self):
        # a rotated sensor reads the projection of the global displacement on its axis
        c, s = np.cos(0.3), np.sin(0.3)
        R = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        phi = np.arange(1.0, 19.0)[:, None]
        modes = ModeSet(freq_hz=[1.0], shapes=phi, dofs=MODEL)
        out = DofMap(test_frames={12: R}).apply(modes, ["12+X"])
        np.testing.assert_allclose(out.shapes[0, 0], c * 1.0 + s * 2.0)
        assert [str(d) for d in out.dofs] == ["12+X"]

    def test_not_a_rotation(self):
        with pytest.raises(ModalabValueError, match="orthonormal"):
            DofMap(test_frames={1: [[2.0, 0, 0], [0, 1, 0], [0, 0, 1]]})
        with pytest.raises(ShapeError, match="3x3"):
            DofMap(model_frames={1: [[1.0, 0], [0, 1]]})


class TestFiles:
    def test_toml(self, tmp_path):
        p = tmp_path / "map.toml"
        p.write_text(
            'same_nodes = true\n'
            '[nodes]\n"103" = 14\n'
            '[dofs]\n"101+Z" = "12-Z"\n"102+X" = { "13+X" = 0.6, "13+Y" = 0.8 }\n'
            '"104+Z" = { node = 13, direction = [0.0, 0.0, -2.0] }\n'
            '[test_frames]\n"12" = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]\n')
        dm = DofMap.from_file(p)
        C = dense(dm.matrix(["101+Z", "102+X", "103+Z", "104+Z", "12+X"], MODEL))
        np.testing.assert_allclose(C[0], -row("12+Z"))
        np.testing.assert_allclose(C[1], 0.6 * row("13+X") + 0.8 * row("13+Y"))
        np.testing.assert_allclose(C[2], row("14+Z"))
        np.testing.assert_allclose(C[3], -row("13+Z"))
        np.testing.assert_allclose(C[4], row("12+Y"), atol=1e-15)
        assert dm.name == "map.toml"

    def test_csv_with_header_comments_and_combinations(self, tmp_path):
        p = tmp_path / "map.csv"
        p.write_text("test_dof,model_dof,factor\n# comment\n101+Z,12-Z\n102+X,13+X,0.6\n102+X,13+Y,0.8\n")
        C = dense(as_dofmap(str(p)).matrix(["101+Z", "102+X"], MODEL))
        np.testing.assert_allclose(C[0], -row("12+Z"))
        np.testing.assert_allclose(C[1], 0.6 * row("13+X") + 0.8 * row("13+Y"))

    def test_csv_bad_line_is_located(self, tmp_path):
        p = tmp_path / "bad.csv"
        p.write_text("101+Z,12+Z\n102+Z\n")
        with pytest.raises(ModalabValueError, match="line 2"):
            DofMap.from_file(p)
        p.write_text("101+Z,12+Q\n")
        with pytest.raises(DofError, match="line 1"):
            DofMap.from_file(p)

    def test_bad_toml_and_missing_file(self, tmp_path):
        p = tmp_path / "bad.toml"
        p.write_text("[dofs\n")
        with pytest.raises(ModalabValueError, match="TOML"):
            DofMap.from_file(p)
        with pytest.raises(ModalabValueError, match="does not exist"):
            DofMap.from_file(tmp_path / "nope.toml")
        p.write_text("[dofz]\n")
        with pytest.raises(ModalabValueError, match=r"DOF map '.*bad\.toml': unknown key 'dofz'; did you mean 'dofs'\?"):
            DofMap.from_file(p)

    def test_an_entry_error_names_the_file_and_the_key(self, tmp_path):
        p = tmp_path / "m.toml"
        p.write_text('[dofs]\n"1+Z" = "1+W"\n')
        with pytest.raises(DofError, match=r"DOF map '.*m\.toml': \[dofs\] '1\+Z': .*'1\+W'"):
            DofMap.from_file(p)
        p.write_text('[dofs]\n"1+Z" = { node = 3, direction = [0, 0, 0] }\n')
        with pytest.raises(ModalabValueError, match=r"m\.toml': \[dofs\] '1\+Z': .*non-zero 3-vector"):
            DofMap.from_file(p)
        p.write_text('[dofs]\n"1+Z" = "999+Z"\n')
        with pytest.raises(DofError, match=r"1\+Z -> 999\+Z.*\(DOF map m\.toml\)"):
            DofMap.from_file(p).matrix(["1+Z"], MODEL)


class TestSelection:
    def test_selection_indices_and_factors(self):
        idx, fac = DofMap(dofs={"101+Z": "13-Z"}).selection(["101+Z", "12+X"], MODEL)
        assert list(idx) == [MODEL.index("13+Z"), MODEL.index("12+X")]
        assert list(fac) == [-1.0, 1.0]

    def test_model_labels(self):
        dm = DofMap(dofs={"101+Z": "13-Z", "102+X": {"12+X": 2.0}})
        labels, scale = dm.model_labels(["101+Z", "102+X", "14-Y"], MODEL)
        assert [str(d) for d in labels] == ["13-Z", "12+X", "14-Y"]
        np.testing.assert_allclose(scale, [1.0, 2.0, 1.0])
        labels, _ = DofMap().model_labels(["12+Z"], ["12-Z"])
        assert [str(d) for d in labels] == ["12+Z"]


def test_a_csv_row_written_with_an_arrow_is_refused_with_the_row_to_write(tmp_path):
    """README once described map lines as 'test_dof -> model_dof': such a row names the CSV form to write."""
    p = tmp_path / "map.csv"
    p.write_text("101+Z -> 12-Z\n")
    with pytest.raises(ModalabValueError, match=r"line 1: .*expected 'test_dof,model_dof\[,factor\]'.*write '101\+Z,12-Z'"):
        DofMap.from_file(p)
