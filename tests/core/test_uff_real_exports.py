"""Situations of other writers' files (issues 14 #8 and 16 #16-17), on synthetic files written with pyuff.

* ``info`` validates with the readers: damaged files it used to report as fine are refused, with the line;
* a reference node of -1 (or 0) means "no reference";
* FRFs whose record 9 data type is 0/1 (general) take their quantity from the units label or ``--quantity``;
* dataset 2420 local displacement frames are applied (modes, FRFs, geometry) or refused (raw records);
* ``info`` lists the modes of a dataset-55 file and says which frequency of a complex mode it prints.
"""
import json
import os

import numpy as np
import pytest
import pyuff

from modalab.core import uff
from modalab.app.cli import info_table, main
from modalab.core.errors import UffError
from modalab.core.frf import FRF
from modalab.core.modes import ModeSet
from modalab.core.records import TimeRecord


def _frf_set(resp, rdir, ref, fdir, y, *, spec=12, units="m/s^2", ref_node=None, func_type=4, x=None):
    x = np.arange(len(y)) * 0.5 if x is None else x
    return pyuff.prepare_58(binary=0, id1="NONE", id2="NONE", id3="NONE", id4="NONE", id5="NONE",
                            func_type=func_type, ver_num=0, load_case_id=0, rsp_ent_name="NONE", rsp_node=resp,
                            rsp_dir=rdir, ref_ent_name="NONE", ref_node=ref if ref_node is None else ref_node,
                            ref_dir=fdir, ord_data_type=6 if np.iscomplexobj(y) else 4, num_pts=len(y),
                            abscissa_spacing=1, abscissa_min=0.0, abscissa_inc=float(x[1] - x[0]),
                            z_axis_value=0.0, abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz",
                            ordinate_spec_data_type=spec, ordinate_axis_units_lab=units,
                            orddenom_spec_data_type=13 if func_type == 4 else 0,
                            orddenom_axis_units_lab="N" if func_type == 4 else "NONE",
                            data=np.asarray(y), x=x, spec_data_type=26)


def _write(path, sets):
    u = pyuff.UFF(str(path))
    u.write_sets(sets, mode="overwrite")
    return path


# ----------------------------------------------------------------------------- info validates
@pytest.fixture
def ascii_frf(tmp_path):
    frf = FRF.from_arrays(np.linspace(0, 10, 21), np.arange(2 * 1 * 21).reshape(2, 1, 21) * (1 + 0.5j),
                          responses=["1+Z", "2+Z"], references=["1+Z"], quantity="accelerance")
    p = tmp_path / "frf.uff"
    uff.write_frf(p, frf, binary=False)
    return p


def _lines(p):
    return p.read_text().splitlines(keepends=True)


def _damaged(ascii_frf):
    """The damage 'info' reported as fine before: (name, text)."""
    lines = _lines(ascii_frf)
    opens = [i for i, ln in enumerate(lines) if ln.strip() == "-1" and i + 1 < len(lines)
             and lines[i + 1].split()[0] == "58"]
    out = {"cut at a dataset boundary": "".join(lines[:opens[-1]])}
    first_data = opens[0] + 13                       # -1, 58, 5 ID lines, records 6-11, then data
    out["fewer values than declared"] = "".join(lines[:first_data] + lines[first_data + 1:])
    r7 = opens[0] + 8
    fields = lines[r7]
    out["declared count above the data"] = "".join(lines[:r7] + [fields[:10] + "%10i" % 25 + fields[20:]]
                                                   + lines[r7 + 1:])
    out["a value that is not a number"] = "".join(lines[:first_data] + [lines[first_data].replace("E", "X", 1)]
                                                  + lines[first_data + 1:])
    return out


def test_info_refuses_the_damage_the_readers_refuse(ascii_frf, tmp_path):
    assert uff.info(ascii_frf)["frf"]["responses"] == ["1+Z", "2+Z"]
    for name, text in _damaged(ascii_frf).items():
        p = tmp_path / "bad.uff"
        p.write_text(text)
        with pytest.raises(UffError) as reader:
            uff.read_frf(p)
        with pytest.raises(UffError) as info:
            uff.info(p)
        assert "bad.uff" in str(info.value), name
        assert info.value.line is not None or "lost" in str(info.value), (name, str(info.value))
        assert main(["info", str(p)]) == 2


def test_info_refuses_a_foreign_file_with_fewer_values(tmp_path):
    """No modalab write tags: the point count of record 7 alone must catch it."""
    y = np.arange(8) * (1 + 1j)
    p = _write(tmp_path / "pyuff.uff", [_frf_set(1, 3, 1, 3, y)])
    assert uff.info(p)["frf"]["lines"] == 8
    lines = _lines(p)
    data0 = 13                                       # -1, 58, 5 ID lines, records 6-11: data from line 14
    (tmp_path / "short.uff").write_text("".join(lines[:data0] + lines[data0 + 1:]))
    with pytest.raises(UffError, match="record 7 calls for"):
        uff.info(tmp_path / "short.uff")


def test_info_table_separates_hammer_points_from_responses(tmp_path, capsys):
    recs = []
    for h, point in enumerate(["1+Z", "4+Z", "1+Z"], start=1):
        data = np.random.default_rng(h).normal(size=(3, 64))
        recs.append(TimeRecord(sample_rate_hz=512.0, data=data, dofs=[point, "19+Z", "20+Y"],
                               roles=["force", "response", "response"], units=["N", "m/s^2", "m/s^2"],
                               trigger_index=8, hit_id=h))
    p = tmp_path / "hits.uff"
    uff.write_records(p, recs)
    d = uff.info(p)["hits"]
    assert d["hammer_points"] == ["1+Z", "4+Z"] and d["hits_per_point"] == {"1+Z": 2, "4+Z": 1}
    assert d["responses"] == ["19+Z", "20+Y"]
    assert main(["info", str(p)]) == 0
    out = capsys.readouterr().out
    assert "{" not in out and "None" not in out           # no Python reprs
    rows = {ln.split("  ")[0].strip(): ln for ln in out.splitlines()}
    assert "1+Z (2 hits), 4+Z (1 hit)" in rows["hammer points"]
    assert rows["responses"].split()[-2:] == ["19+Z,", "20+Y"]
    assert main(["info", str(p), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["hits"]["hits"] == 3


# ----------------------------------------------------------------------------- reference node -1
def test_reference_node_minus_one_means_none(tmp_path):
    y = np.sin(np.arange(16.0))
    p = _write(tmp_path / "milestone.uff", [_frf_set(3, 2, None, 0, y, ref_node=-1, func_type=1, spec=12,
                                                     x=np.arange(16) / 16.0)])
    recs = uff.read_records(p)
    assert recs[0].dofs[0].node == 3 and not recs[0].force_dofs
    np.testing.assert_allclose(recs[0].data[0], y)
    assert uff.info(p)["hits"]["responses"] == ["3+Y"]
    q = _write(tmp_path / "frf_noref.uff", [_frf_set(3, 2, None, 3, y * (1 + 1j), ref_node=-1)])
    with pytest.raises(UffError, match="no reference DOF"):
        uff.read_frf(q)


# ----------------------------------------------------------------------------- quantity
def test_general_ordinate_type_quantity_from_label_or_cli(tmp_path, capsys):
    y = (np.arange(6) + 1) * (1 - 1j)
    labelled = _write(tmp_path / "labelled.uff", [_frf_set(2, 3, 1, 3, y, spec=1, units="m/s^2")])
    assert uff.read_frf(labelled).quantity == "accelerance"
    mob = _write(tmp_path / "mob.uff", [_frf_set(2, 3, 1, 3, y, spec=1, units="mm/s")])
    f = uff.read_frf(mob)
    assert f.quantity == "mobility"
    np.testing.assert_allclose(f.H[0, 0], 1e-3 * y)
    bare = _write(tmp_path / "bare.uff", [_frf_set(2, 3, 1, 3, y, spec=1, units="NONE")])
    with pytest.raises(UffError, match="--quantity accelerance"):
        uff.read_frf(bare)
    assert main(["info", str(bare)]) == 2
    assert "--quantity" in capsys.readouterr().err
    assert main(["info", str(bare), "--quantity", "mobility", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["frf"]["quantity"] == "mobility"
    with uff.assume_quantity("receptance"):
        assert uff.read_frf(bare).quantity == "receptance"
        with pytest.raises(UffError, match="says receptance"):
            uff.read_frf(labelled)                      # the file says accelerance: no silent relabelling
    assert main(["info", str(labelled), "--quantity", "mobility"]) == 2
    assert "MODALAB_QUANTITY" not in os.environ          # restored after the command


def test_quantity_reaches_worker_processes(tmp_path, monkeypatch):
    import concurrent.futures as cf
    import multiprocessing as mp

    bare = _write(tmp_path / "bare.uff", [_frf_set(2, 3, 1, 3, np.ones(4) * 1j, spec=1, units="NONE")])
    with uff.assume_quantity("mobility"):
        with cf.ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as ex:
            assert ex.submit(_quantity_of, str(bare)).result(timeout=120) == "mobility"
    monkeypatch.setenv("MODALAB_QUANTITY", "receptance")
    assert uff.read_frf(bare).quantity == "receptance"
    monkeypatch.setenv("MODALAB_QUANTITY", "accel")
    with pytest.raises(UffError, match="MODALAB_QUANTITY"):
        uff.read_frf(bare)


def _quantity_of(path):
    return uff.read_frf(path).quantity


# ----------------------------------------------------------------------------- dataset 2420 frames
def _rot_z(deg):
    """Rows: the local X, Y, Z axes in global coordinates."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def _frames_file(path, sets, *, disp_cs=(5, 1), deg=33.0, cs_type=0):
    R = _rot_z(deg)
    cs = pyuff.prepare_2420(Part_UID=1, Part_Name="part", CS_sys_labels=[5], CS_types=[cs_type], CS_colors=[8],
                            CS_names=["sensor"], CS_matrices=[np.vstack([R, [0.5, 0.0, 0.0]])])
    nodes = pyuff.prepare_2411(node_nums=[1, 2], def_cs=[5, 1], disp_cs=list(disp_cs), color=[1, 1],
                               x=[1.0, 2.0], y=[0.0, 0.0], z=[0.0, 0.0])
    return _write(path, [cs, nodes] + sets), R


def test_modes_in_local_frames_are_rotated_to_global(tmp_path):
    vg = np.array([[0.3, -0.8, 0.5], [0.0, 1.0, 0.2]])          # global shape at nodes 1, 2
    R = _rot_z(33.0)
    vl = vg.copy()
    vl[0] = R @ vg[0]                                           # node 1 stored in its local frame
    mode = pyuff.prepare_55(id1="Mode 1", id2="NONE", id3="NONE", id4="NONE", id5="NONE", model_type=1,
                            analysis_type=2, data_ch=2, spec_data_type=8, data_type=2, n_data_per_node=3,
                            r1=vl[:, 0], r2=vl[:, 1], r3=vl[:, 2], load_case=1, mode_n=1, freq=12.0, modal_m=1.0,
                            modal_damp_vis=0.01, modal_damp_his=0.0, node_nums=np.array([1, 2]))
    p, _ = _frames_file(tmp_path / "gvt.unv", [mode])
    ms = uff.read_modes(p, dofs=["1+X", "1+Y", "1+Z", "2+X", "2+Y", "2+Z"])
    np.testing.assert_allclose(ms.shapes[:, 0], vg.reshape(-1), atol=1e-6)      # pyuff writes E13.5
    assert ms.metadata["rotated_to_global"] == [1]
    geo = uff.read_geometry(p)                                  # node 1 defined in frame 5 too
    np.testing.assert_allclose(geo[1], R.T @ [1.0, 0.0, 0.0] + [0.5, 0.0, 0.0])
    assert geo[2] == (2.0, 0.0, 0.0)
    assert uff.info(p)["coordinate_systems"] == {"5": "rotated"}


def test_frf_triad_in_a_local_frame_is_rotated_and_a_lone_direction_refused(tmp_path):
    rng = np.random.default_rng(4)
    Hg = rng.normal(size=(3, 5)) + 1j * rng.normal(size=(3, 5))   # global X, Y, Z responses of node 1 to 2+Z
    R = _rot_z(33.0)
    Hl = R @ Hg
    sets = [_frf_set(1, c + 1, 2, 3, Hl[c]) for c in range(3)]
    p, _ = _frames_file(tmp_path / "triax.unv", sets)
    f = uff.read_frf(p)
    np.testing.assert_allclose(f.H[:, 0], Hg, atol=1e-12)
    assert f.metadata["rotated_to_global"] == [1]
    gap = sets + [_frf_set(1, c + 1, 9, 3, Hl[c]) for c in range(2)]      # 1+Z / 9+Z missing
    gp, _ = _frames_file(tmp_path / "gap.unv", gap)
    np.testing.assert_allclose(uff.read_frf(gp, references=["2+Z"]).H[:, 0], Hg, atol=1e-12)
    with pytest.raises(UffError, match="missing"):
        uff.read_frf(gp)                     # the triad with 9+Z cannot be rotated: never returned unrotated
    lone, _ = _frames_file(tmp_path / "lone.unv", sets[:1])
    with pytest.raises(UffError, match="X, Y and Z are needed"):
        uff.read_frf(lone)
    rec = _frf_set(1, 3, None, 0, np.ones(8), ref_node=0, func_type=1, x=np.arange(8) / 8.0)
    recs, _ = _frames_file(tmp_path / "rec.unv", [rec])
    with pytest.raises(UffError, match="rotated displacement frames"):
        uff.read_records(recs)
    cyl, _ = _frames_file(tmp_path / "cyl.unv", sets, cs_type=1)
    with pytest.raises(UffError, match="cylindrical"):
        uff.read_frf(cyl)


def test_identity_frames_change_nothing(tmp_path):
    sets = [_frf_set(1, 3, 2, 3, np.arange(4) * (1 + 1j))]
    p, _ = _frames_file(tmp_path / "ident.unv", sets, deg=0.0)
    f = uff.read_frf(p)
    np.testing.assert_array_equal(f.H[0, 0], np.arange(4) * (1 + 1j))
    assert "rotated_to_global" not in f.metadata


# ----------------------------------------------------------------------------- dataset 55 in info
def test_info_lists_modes_and_says_which_frequency(tmp_path, capsys):
    fn, zeta = np.array([10.0, 25.0]), np.array([0.05, 0.02])
    lam = -zeta * 2 * np.pi * fn + 1j * 2 * np.pi * fn * np.sqrt(1 - zeta ** 2)
    fd = lam.imag / (2 * np.pi)
    sets = []
    for k in range(2):
        sets.append(pyuff.prepare_55(id1=f"Mode {k + 1}", id2=f"Freq {fd[k]:.4f} Hz", id3="NONE", id4="NONE",
                                     id5="NONE", model_type=1, analysis_type=3, data_ch=2, spec_data_type=8,
                                     data_type=5, n_data_per_node=3, r1=np.array([1.0 + 0.1j]),
                                     r2=np.array([0j]), r3=np.array([0.5 - 0.2j]), load_case=1, mode_n=k + 1,
                                     eig=lam[k], modal_a=0j, modal_b=0j, node_nums=np.array([7])))
    p = _write(tmp_path / "cmodes.uff", sets)
    d = uff.info(p)["modes"]
    assert d["n_modes"] == 2
    for k, row in enumerate(d["table"]):
        assert row["complex"] and row["header_states"] == "damped"
        assert row["freq_undamped_hz"] == pytest.approx(fn[k], rel=1e-5)     # pyuff writes E13.5
        assert row["freq_damped_hz"] == pytest.approx(fd[k], rel=1e-5)
        assert row["damping"] == pytest.approx(zeta[k], rel=1e-4)
    text = "\n".join(info_table(uff.info(p)))
    assert "f_n: undamped natural frequency" in text and "f_d: damped" in text
    assert f"{fd[0]:.4f}" in text and "(damped)" in text
    real = tmp_path / "real.uff"
    uff.write_modes(real, ModeSet(freq_hz=[5.0, 9.0], damping=[0.01, 0.02], shapes=[[1.0, 0.2]], dofs=["3+Z"]))
    assert main(["info", str(real)]) == 0
    out = capsys.readouterr().out
    assert "f [Hz]" in out and "5.0000" in out and "9.0000" in out and "f_d" not in out


def test_frequency_only_mode_set_round_trips(tmp_path):
    """Issue 16 #12: writing a mode set without shapes raised 'max() arg is an empty sequence'."""
    m = ModeSet(freq_hz=[3.5, 7.25], damping=[0.01, 0.02], shapes=np.zeros((0, 2)), dofs=[])
    p = tmp_path / "f_only.uff"
    uff.write_modes(p, m)
    r = uff.read_modes(p)
    np.testing.assert_array_equal(r.freq_hz, m.freq_hz)
    np.testing.assert_array_equal(r.damping, m.damping)
    assert r.dofs == [] and r.shapes.shape == (0, 2)
    assert "2 modes (frequencies and damping only, no shapes)" in "\n".join(info_table(uff.info(p)))
    assert len(pyuff.UFF(str(p)).read_sets()) == 2


def test_info_table_of_frfs_has_no_python_reprs(tmp_path, capsys):
    frf = FRF.from_arrays(np.linspace(0, 10, 11), np.ones((1, 2, 11)) * (1 + 1j), responses=["5+X"],
                          references=["1+Z", "2-Z"], quantity="mobility",
                          metadata={"estimator": "H1", "exp_window": None, "hit_ids": [1, 2, 3]})
    p = tmp_path / "f.uff"
    uff.write_frf(p, frf)
    assert main(["info", str(p)]) == 0
    out = capsys.readouterr().out
    for repr_mark in ("None", "{", "[", "'"):
        assert repr_mark not in out.replace("[m/s/N]", ""), out
    assert "1 response x 2 references, mobility" in out and "2-Z" in out
    assert "roving-hammer export" in out


def test_modes_json_of_identify_is_read_and_damage_is_named(tmp_path):
    from modalab.core.errors import ModalabValueError

    m = ModeSet(freq_hz=[4.0, 8.0], damping=[0.01, 0.03], shapes=[[1.0, 0.5], [0.2, -1.0]], dofs=["1+Z", "2+Y"])
    p = tmp_path / "identify.json"
    p.write_text(json.dumps({"input": "frf.uff", "modes": m.to_dict(), "report": {}}))
    r = ModeSet.from_json(p)
    np.testing.assert_array_equal(r.freq_hz, m.freq_hz)
    assert [str(d) for d in r.dofs] == ["1+Z", "2+Y"]
    for text, needle in (('{"modes": {"freq_hz": [1.0]', "not valid JSON"), ('{"a": 1}', "needs at least 'freq_hz'"),
                         ("[1, 2]", "does not hold a mode set"),
                         ('{"mac": [], "pairing": {}, "pairs": []}', "it is a correlation .*run identify again"),
                         ('{"findings": [], "fit": {}}', "it is a diagnosis")):
        p.write_text(text)
        with pytest.raises(ModalabValueError, match=needle) as ei:
            ModeSet.from_json(p)
        assert "identify.json" in str(ei.value)
