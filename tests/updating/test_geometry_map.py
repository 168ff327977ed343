"""Test nodes onto model grids by geometry (issue 16 #5): identity, a rigid transform, refusals."""
import numpy as np
import pytest

from modalab.core.errors import DofError
from updating.correlation.dofmap import geometry_map

# model grids: a 5 x 3 plate of 0.1 m pitch; test nodes numbered 1.. at some of them
GRID = {100 + 10 * i + j: (0.1 * i, 0.1 * j, 0.0) for i in range(5) for j in range(3)}
TEST_AT = [100, 112, 121, 140, 132]
TEST = {k + 1: GRID[g] for k, g in enumerate(TEST_AT)}


def test_same_frame_maps_each_test_node_to_its_grid():
    dm, rep = geometry_map(TEST, GRID)
    assert {int(k): v["model_node"] for k, v in rep["nodes"].items()} == dict(zip(range(1, 6), TEST_AT))
    assert rep["max_distance_m"] == 0.0
    C = dm.matrix(["3+Z", "4-Y"], [f"{g}+{a}" for g in GRID for a in "XYZ"]).toarray()
    cols = [f"{g}+{a}" for g in GRID for a in "XYZ"]
    assert C[0, cols.index("121+Z")] == 1.0 and C[1, cols.index("140+Y")] == -1.0


def test_small_offsets_are_reported_not_hidden():
    off = {k: (x + 0.003, y, z + 0.002) for k, (x, y, z) in TEST.items()}     # sensors glued on the surface
    _, rep = geometry_map(off, GRID)
    assert rep["max_distance_m"] == pytest.approx(np.hypot(0.003, 0.002))
    assert all(v["distance_m"] > 0 for v in rep["nodes"].values())


def test_rigid_transform_is_fitted_and_directions_rotated():
    # an irregular model mesh (no symmetry), test geometry in its own rotated and shifted frame
    rng = np.random.default_rng(0)
    grid = {100 + k: tuple(v) for k, v in enumerate(rng.uniform(0, 1, size=(40, 3)) * [1.0, 0.6, 0.2])}
    at = [100, 107, 115, 123, 131, 139]
    test = {k + 1: grid[g] for k, g in enumerate(at)}
    th = np.deg2rad(90.0)
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    t = np.array([2.0, -1.0, 0.5])
    # test geometry in its own frame: x_test = R^T (x_model - t)
    moved = {k: tuple(R.T @ (np.array(v) - t)) for k, v in test.items()}
    dm, rep = geometry_map(moved, grid)
    assert {int(k): v["model_node"] for k, v in rep["nodes"].items()} == dict(zip(range(1, 7), at))
    assert rep["max_distance_m"] < 1e-9
    np.testing.assert_allclose(rep["rotation"], R, atol=1e-9)
    # a sensor along the test frame's +X reads the model's +Y (rotated by 90 degrees)
    cols = [f"{g}+{a}" for g in grid for a in "XYZ"]
    C = dm.matrix(["1+X"], cols).toarray()
    assert C[0, cols.index("100+Y")] == pytest.approx(1.0)


def test_a_symmetric_layout_is_ambiguous_not_guessed():
    th = np.deg2rad(90.0)
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    moved = {k: tuple(R.T @ (np.array(v) - [2.0, -1.0, 0.5])) for k, v in TEST.items()}
    with pytest.raises(DofError, match="ambiguous"):
        geometry_map(moved, GRID)


def test_refuses_a_geometry_that_does_not_fit():
    far = dict(TEST)
    far[6] = (5.0, 5.0, 5.0)
    with pytest.raises(DofError, match="no model node within"):
        geometry_map(far, GRID)


def test_refuses_two_test_nodes_on_one_grid():
    two = {1: (0.0, 0.0, 0.0), 2: (0.004, 0.0, 0.0), 3: (0.2, 0.1, 0.0)}
    with pytest.raises(DofError, match="all map onto model node 100"):
        geometry_map(two, GRID)


def test_missing_test_coordinates_are_named():
    with pytest.raises(DofError, match=r"\[7\]"):
        geometry_map(TEST, GRID, test_nodes=[1, 7])


def test_mode_file_carries_its_geometry(tmp_path):
    from modalab.core.modes import ModeSet

    ms = ModeSet(freq_hz=[3.0, 7.0], shapes=np.eye(2), dofs=["1+Z", "2+Z"], coordinates={1: (0.0, 0.1, 0.2),
                                                                                        2: (1.5, -0.25, 0.0)})
    ms.to_uff(tmp_path / "m.uff")
    back = ModeSet.from_uff(tmp_path / "m.uff")
    assert back.coordinates == ms.coordinates
    np.testing.assert_array_equal(back.shapes, ms.shapes)
    assert ModeSet.from_dict(ms.to_dict()).coordinates == ms.coordinates
