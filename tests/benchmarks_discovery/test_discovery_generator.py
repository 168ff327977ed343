"""The discovery benchmark's generator itself (benchmarks/discovery): its independent truth simulator against
closed-form beam frequencies, reciprocity of its FRFs, its files read back by modalab as a user's files would
be, byte-identical output for one seed, and the scorer's location rule."""
from __future__ import annotations

import ast
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.discovery import score                                   # noqa: E402
from benchmarks.discovery.cases import build_truth, make_case           # noqa: E402
from benchmarks.discovery.generate import generate_one, simulate, write_case   # noqa: E402
from benchmarks.discovery.truthsim import TruthModel, box, tube         # noqa: E402

STEEL = dict(E=2.1e11, rho=7850.0, nu=0.3)
CONTROL_SEED = 11          # (11 // 2) % 6 == 5: a control, no magnitude search (fast)


def _line(n, L, sec, fix):
    G = STEEL["E"] / (2 * (1 + STEEL["nu"]))
    m = TruthModel()
    for i in range(n + 1):
        m.add_node(i + 1, [i * L / n, 0.0, 0.0])
    for i in range(n):
        m.beam(i + 1, i + 2, np.array([0.0, 1.0, 0.0]), sec, STEEL["E"], G, STEEL["rho"], 0.0)
    fix(m, n)
    return m, G


def test_the_generator_does_not_import_the_code_it_judges():
    forbidden = ("modalab", "updating", "hardware_sim", "identification")
    for name in ("truthsim.py", "cases.py", "topologies.py", "generate.py", "writers.py"):
        tree = ast.parse((ROOT / "benchmarks" / "discovery" / name).read_text())
        for node in ast.walk(tree):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            assert not [m for m in mods if m.split(".")[0] in forbidden], (name, mods)


def test_simply_supported_thick_beam_matches_timoshenko_closed_form():
    """Bending modes of a simply supported box beam (L/h = 5): exact Timoshenko roots (shear and rotary
    inertia), and clearly below Euler-Bernoulli, so the shear terms are really there."""
    sec = box(0.08, 0.12, 0.006)
    L = 0.6
    m, G = _line(40, L, sec, lambda m, n: (m.fix(1, "1234"), m.fix(n + 1, "23")))
    f = m.frequencies(8)
    for I, k in ((sec.Iy, sec.kz), (sec.Iz, sec.ky)):
        a = np.pi / L
        A2 = STEEL["rho"] ** 2 * I / (k * G)
        B = -(STEEL["rho"] * sec.A + STEEL["rho"] * I * a * a + STEEL["E"] * I * STEEL["rho"] * a * a / (k * G))
        C = STEEL["E"] * I * a ** 4
        f_timo = np.sqrt((-B - np.sqrt(B * B - 4 * A2 * C)) / (2 * A2)) / (2 * np.pi)
        f_euler = np.sqrt(STEEL["E"] * I / (STEEL["rho"] * sec.A)) * a * a / (2 * np.pi)
        near = f[np.argmin(np.abs(f - f_timo))]
        assert near == pytest.approx(f_timo, rel=2e-4)
        assert f_timo < 0.93 * f_euler


def test_slender_cantilever_tube_matches_euler_bernoulli():
    sec = tube(0.01, 0.009)
    L = 1.0
    m, _ = _line(30, L, sec, lambda m, n: m.fix(1))
    f = m.frequencies(4)
    f1 = 1.875104 ** 2 * np.sqrt(STEEL["E"] * sec.Iz / (STEEL["rho"] * sec.A * L ** 4)) / (2 * np.pi)
    assert f[0] == pytest.approx(f1, rel=2e-3) and f[1] == pytest.approx(f1, rel=2e-3)   # two planes


def test_truth_frfs_are_reciprocal_with_hysteretic_damping_a_flexible_joint_and_springs():
    case = make_case(8)                          # mounted frame: mounts with loss factor, per-section eta
    phys = {"physics": "joint_flexibility", "nodes": [n for n in sorted(case.frame.joints())][:1],
            "member": case.frame.joints()[sorted(case.frame.joints())[0]][0], "axis": 2, "value": 500.0,
            "elements": []}
    t = build_truth(case.frame, case.refine, case.errors, case.eta, phys)
    dofs = [(n, d) for n, d in [(h[0], abs(h[1])) for h in case.hits[:6]]] + [(5000 + phys["nodes"][0], 6)]
    X = t.receptance([13.0, 71.5, 240.0], dofs, dofs)
    assert np.count_nonzero(np.abs(X) > 1e-12 * np.abs(X).max()) > X.size // 3   # (planar: some pairs 0)
    np.testing.assert_allclose(X, np.transpose(X, (1, 0, 2)), rtol=1e-9, atol=1e-9 * np.abs(X).max())
    assert np.abs(X.imag).max() > 1e-3 * np.abs(X).max()          # the structure is damped


@pytest.fixture(scope="module")
def control_sim():
    case = make_case(CONTROL_SEED)
    return case, simulate(case)


@pytest.fixture(scope="module")
def control_case(tmp_path_factory, control_sim):
    case, sim = control_sim
    return write_case(case, tmp_path_factory.mktemp("disc"), sim)


def test_a_written_case_reads_back_through_modalab(control_case, control_sim):
    from modalab.core import uff
    from updating.fe.bulk import build_model, read_bdf

    truth = json.loads((control_case / "truth.json").read_text())
    bulk = read_bdf(control_case / "nominal.bdf")
    model = build_model(bulk)
    assert bulk.case_control.sol == "103"
    elems = truth["nominal"]["elements"]
    assert len(model.elements) == len(elems)
    frf = uff.read_frf(control_case / "measured.uff")
    assert frf.quantity == "accelerance"
    assert [str(d) for d in frf.responses] == truth["measurement"]["hits"]
    assert [str(d) for d in frf.references] == truth["measurement"]["sensors"]
    assert frf.H.shape == (len(truth["measurement"]["hits"]), len(truth["measurement"]["sensors"]), 2000)
    assert frf.freq_hz[-1] == pytest.approx(truth["measurement"]["band_hz"][1], rel=1e-9)
    geo = uff.read_geometry(control_case / "measured.uff")
    for n, xyz in geo.items():                   # measured nodes are nominal grids at their coordinates
        np.testing.assert_allclose(xyz, bulk.grid_xyz(n), atol=1e-9)
    # the file holds what the truth simulator gives, within the noise the coherence reports
    case, (f, A, H1, coh) = control_sim
    np.testing.assert_allclose(frf.H, H1, rtol=1e-5, atol=1e-9 * np.abs(H1).max())
    good = coh > 0.99
    rel = np.abs(H1 - A)[good] / np.abs(A)[good]
    pred = np.sqrt((1 - coh[good]) / (2 * case.n_avg * coh[good]))
    assert 0.3 < np.median(rel) / np.median(pred) < 3.0


def test_truth_json_gives_the_truth_s_frequencies_without_and_with_the_concealed_effect(control_case):
    """A ground spring (seed 1251) raises a bending mode 2.7 %: truth.json gives both spectra (it gave the one
    without the effect only, under a name that read as what the test measured); a control's are the same."""
    case = make_case(1251)
    info = case.info
    with_effect = build_truth(case.frame, case.refine, case.errors, case.eta, case.physics).frequencies(30)
    without = build_truth(case.frame, case.refine, case.errors, case.eta, None).frequencies(30)
    n = len(info["truth_frequencies_hz"])
    np.testing.assert_allclose(info["truth_frequencies_with_effect_hz"][:n], with_effect[:n], rtol=1e-5)
    np.testing.assert_allclose(info["truth_frequencies_hz"], without[:n], rtol=1e-5)
    assert info["truth_frequencies_with_effect_hz"][1] / info["truth_frequencies_hz"][1] == pytest.approx(1.027, abs=1e-3)
    ctl = json.loads((control_case / "truth.json").read_text())
    assert ctl["control"] and ctl["truth_frequencies_with_effect_hz"] == ctl["truth_frequencies_hz"]


def test_same_seed_gives_byte_identical_files(control_case, tmp_path):
    r = generate_one(CONTROL_SEED, tmp_path)
    for name in ("nominal.bdf", "measured.uff", "truth.json", "params.toml"):
        assert (Path(r["dir"]) / name).read_bytes() == (control_case / name).read_bytes(), name


def test_score_counts_a_finding_within_one_node_and_flags_control_findings():
    truth = {"control": False, "seed": 1, "environment": [],
             "concealed": [{"physics": "added_mass", "nodes": [3], "elements": [], "dofs": ["3"], "value": 0.1,
                            "unit": "kg"}],
             "nominal": {"edges": [[1, 2], [2, 3], [3, 4], [4, 5]],
                         "elements": {"1": [1, 2], "2": [2, 3], "3": [3, 4], "4": [4, 5]}}}
    diag = {"findings": [{"physics": "added_mass", "nodes": [4], "elements": [], "dofs": ["4"],
                          "values": [{"name": "m", "value": 0.12, "unit": "kg", "std": 0.01}]},
                         {"physics": "ground_spring", "nodes": [1], "elements": [], "dofs": ["1+Z"],
                          "values": [{"name": "k", "value": 1e3, "unit": "N/m", "std": 1.0}]}],
            "fit": {"nominal": {"frf_error_held_out": 1.0}, "parameters_only": {"frf_error_held_out": 0.5},
                    "with_physics": {"frf_error_held_out": 0.1}}}
    r = score.score_case(truth, score.parse_diagnosis(diag), {"error": None})
    assert r["right"] and r["distance"] == 1 and r["spurious"] == 1
    assert r["value_error"] == pytest.approx(0.2)
    diag["findings"][0]["nodes"] = [5]
    r = score.score_case(truth, score.parse_diagnosis(diag), {"error": None})
    assert not r["right"] and r["kind_right"] and r["distance"] == 2
    truth["control"] = True
    r = score.score_case(truth, score.parse_diagnosis(diag), {"error": None})
    assert not r["right"] and r["spurious"] == 2


def test_score_marks_a_match_through_an_ambiguous_findings_alternative():
    truth = {"control": False, "seed": 1, "environment": [],
             "concealed": [{"physics": "ground_spring", "nodes": [2], "elements": [], "dofs": ["2+Y"], "value": 1e4,
                            "unit": "N/m"}],
             "nominal": {"edges": [[1, 2], [2, 3], [3, 4], [4, 5]],
                         "elements": {"1": [1, 2], "2": [2, 3], "3": [3, 4], "4": [4, 5]}}}
    diag = {"findings": [{"physics": "ground_spring", "nodes": [5], "elements": [], "dofs": ["5+Y"],
                          "values": [{"name": "k", "value": 1e4, "unit": "N/m", "std": 1.0}],
                          "alternatives": [{"physics": "ground_spring", "nodes": [2]}]}],
            "fit": {}}
    r = score.score_case(truth, score.parse_diagnosis(diag), {"error": None})
    assert r["right"] and r["via_alternative"] and r["distance"] == 0
    assert "(or ground_spring at n 2)" in r["findings"][0]
    diag["findings"][0]["nodes"] = [2]          # the best-fitting explanation itself is right
    r = score.score_case(truth, score.parse_diagnosis(diag), {"error": None})
    assert r["right"] and not r["via_alternative"]


def test_visibility_from_the_truth_alone_separates_an_unseen_effect():
    from benchmarks.discovery.visibility import effect_to_noise
    # seed 36: a Z spring on a planar frame measured and hit in its plane only; seed 0: a spring in the plane
    assert effect_to_noise(36)["effect_to_noise"] < 1e-6
    assert effect_to_noise(0)["effect_to_noise"] > 100


def test_summary_reports_the_rate_on_visible_effects_beside_the_whole():
    def r(right, en):
        return {"case": f"c{en}", "truth": "added_mass", "right": right, "spurious": 0, "error": None, "wall_s": 1.0, "cpu_s": 1.0,
                "heldout": {}, "effect_to_noise": en, "value_error": None}
    text, s = score.summary([r(True, 50.0), r(False, 20.0), r(False, 0.0)])
    assert "1/3" in text.splitlines()[1]
    assert s["right_within_one_node_visible"] == 0.5 and "below the noise: 1 case" in text

