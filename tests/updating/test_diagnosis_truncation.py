"""The tails a record cuts off (``updating.diagnosis.truncation.restore_tails``) and the FRF diagnosis of exact,
unwindowed data (issue 14 #2: without the exponential window the exact model's E and ρ moved by
−0.14..−0.27 %, 3.5-7.6 std, on the demo chain without noise).

The truth of the unit tests is not the formula of the module: the "measured" FRFs are the DFTs of sampled modal
impulse responses cut by a 4 s record that starts 0.0625 s before the impulse, and the truth is the same DFT of
a record 64 times longer, on the same lines."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from modalab.core.frf import FRF
from updating.diagnosis.truncation import restore_tails

FS, N, N0 = 256.0, 1024, 16                              # 4 s record, the impulse 0.0625 s in
#: (Hz, ζ): a bounce mode that keeps 78 % at 4 s, one that keeps 25 %, one 2 %, two that have died out
MODES = [(1.0, 0.01), (5.5, 0.01), (15.7, 0.01), (40.0, 0.01), (71.0, 0.01)]
PHI = np.array([[1.0, 0.6, -0.8, 0.5, 0.3], [0.4, -1.0, 0.7, 0.9, -0.6]])   # 2 responses, modal mass 1


def _record(n: int, beta: float = 0.0) -> np.ndarray:
    """Accelerance of the two responses to an impulse at sample N0 of an n-sample record (window e^{−β(t−t0)}),
    as the spectral estimate forms it: Δt · DFT(response) / DFT(impulse), on the lines of the n-sample record."""
    t = (np.arange(n) - N0) / FS
    acc = np.zeros((2, n))
    for (f, z), phi in zip(MODES, PHI.T):
        lam = -z * 2 * np.pi * f + 1j * 2 * np.pi * f * np.sqrt(1 - z * z)
        A = phi[:, None] * phi[0] / (2j * lam.imag)                # receptance residue, reference = response 0
        acc += np.where(t >= 0, 2 * np.real(A * lam ** 2 * np.exp(lam * np.maximum(t, 0))), 0.0)
    acc *= np.exp(-beta * np.maximum(t, 0))
    k = np.arange(n // 2 + 1)
    return np.fft.rfft(acc, axis=1) / FS / np.exp(-2j * np.pi * k * N0 / n)


def _frf(H, beta=0.0):
    f = np.arange(H.shape[-1]) * FS / N
    return FRF(freq_hz=f[1:], H=H[:, None, 1:], responses=["1+Z", "2+Z"], references=["1+Z"],
               quantity="accelerance", metadata={"estimator": "H1"}, window_beta_per_s=beta)


@pytest.fixture(scope="module")
def cut_and_truth():
    return _frf(_record(N)), _frf(_record(64 * N)[:, ::64])


def _err(H, truth, lo, hi):
    sel = (truth.freq_hz >= lo) & (truth.freq_hz < hi)
    return float(np.linalg.norm(H[..., sel] - truth.H[..., sel]) / np.linalg.norm(truth.H[..., sel]))


def test_the_cut_tails_are_restored_to_the_long_record(cut_and_truth):
    cut, truth = cut_and_truth
    assert _err(cut.H, truth, 4, 10) > 0.1                 # the cut: 25 % of the 5.5 Hz mode
    r = restore_tails(cut)
    assert r.t0 == pytest.approx(N0 / FS, abs=2e-3)
    assert sorted(np.round(r.poles.imag / (2 * np.pi), 1)) == [1.0, 5.5, 15.7]
    # the bounce mode keeps 78 % past the record: its lines (up to halfway to 5.5 Hz) are to be left out
    assert r.cut_hz == pytest.approx((1.0 + 5.5) / 2, abs=0.1)
    # measured: 22 % -> 0.03 % at 1.5-4 Hz, 25.6 % -> 0.005 % at 4-10 Hz, 2.2 % -> 0.01 % at 10-30 Hz
    for lo, hi in ((1.5, 4), (4, 10), (10, 30), (30, 100)):
        assert _err(r.frf.H, truth, lo, hi) < 0.1 * max(_err(cut.H, truth, lo, hi), 0.005), (lo, hi)


def test_a_windowed_record_is_left_alone():
    beta = np.log(100) / (N / FS)                          # the usual window: 1 % left at the record's end
    frf = _frf(_record(N, beta), beta)
    r = restore_tails(frf)
    assert r.poles.size == 0 and r.cut_hz == 0 and r.frf is frf


def test_synthesised_frfs_are_left_alone(cut_and_truth):
    cut, _ = cut_and_truth
    syn = dataclasses.replace(cut, metadata={}) if dataclasses.is_dataclass(cut) else cut._replace(metadata={})
    assert restore_tails(syn).poles.size == 0


ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo_project"
POINTS = "200+Z 204+Z 208+Z 213+Z 217+Z 218+Z 100+Z 115+Z 308+Z 408+Z 508+Y 600+Z 608+Z".split()
REFS = "218+Z 200+Z 508+Y".split()


def _quiet_hits(path: Path, n_samples: int = 8192, points=POINTS):
    """The hits of tests/cli/test_exact_chain.py (``modalab sim`` of the demo's nominal.bdf, seed 1) without
    sensor and converter noise and without placement scatter: what is left is the signal chain and the record
    (``n_samples`` at 2048 Hz: 8192 is the default 4 s)."""
    from hardware_sim.demo import demo_channels, demo_setup
    from hardware_sim.hammer import Hammer
    from hardware_sim.lab import SimulatedLab, simulate_roving_test
    from modalab.app.stages._sim import _sim_structure
    from modalab.core import uff
    st, _ = _sim_structure(str(DEMO / "nominal.bdf"))
    ch = [dataclasses.replace(c, noise_v_rms=0.0) for c in demo_channels(points[0], REFS)]
    lab = SimulatedLab(st, ch, dataclasses.replace(demo_setup(n_samples=n_samples), adc_noise_v_rms=0.0),
                       hammer=Hammer(placement_scatter_m=0.0), rng=np.random.default_rng(1))
    lab.prepare(points)
    recs = simulate_roving_test(lab, points, hits_per_point=3)
    for i, r in enumerate(recs, start=1):
        r.hit_id = i
        r.metadata = {**(r.metadata or {}), "backend": "sim"}
    uff.write_geometry(path, st.coords)
    uff.write_records(path, recs, append=True)


@pytest.mark.slow
def test_the_frf_diagnosis_of_exact_unwindowed_data_leaves_e_and_rho_at_nominal(tmp_path, caplog):
    """Exact hits without noise, ``frf`` without a window, ``diagnose``: every E and ρ within 0.03 % and 2 of
    its stated standard deviations of nominal (measured: −0.001..+0.005 %, at most 0.7 std; before the tails
    were restored −0.14..−0.27 %, 3.5-7.6 std, while the fit counted the leakage as noise)."""
    from modalab.app.cli import main
    _quiet_hits(tmp_path / "hits.uff")
    assert main(["frf", str(tmp_path / "hits.uff"), "-o", str(tmp_path / "frf.uff"), "--no-plot"]) == 0
    with caplog.at_level("WARNING", logger="updating.diagnosis.fit"):
        assert main(["diagnose", str(DEMO / "nominal.bdf"), str(tmp_path / "frf.uff"),
                     "--json", str(tmp_path / "diag.json")]) == 0
    said = [r.getMessage() for r in caplog.records if "leakage of up to" in r.getMessage()]
    assert len(said) == 1 and "restored" in said[0], said
    d = json.loads((tmp_path / "diag.json").read_text())
    assert d["findings"] == []
    for name, v in d["parameters"].items():
        if v["mode"] == "factor":
            assert abs(v["updated"] - 1.0) < 3e-4 and abs(v["updated"] - 1.0) < 2 * v["std"], (name, v)


@pytest.mark.slow
def test_a_16_s_record_of_the_exact_demo_leaves_diagnose_and_update_at_nominal(tmp_path):
    """Exact hits without noise in 16 s records (``--samples 32768``), ``frf`` without a window, then
    ``diagnose`` and ``identify --band 5 700`` + ``update`` with the demo's parameter file: no finding, E and ρ
    within 0.03 % of nominal in both (measured: at most 0.0014 % in diagnose, 0.3 of its std; 0.0006 % in update).

    Before, the simulated lab took the model's pitch and roll on its bungees (0.105 and 0.239 Hz) for free
    rigid-body modes (:func:`modalab.core.structure._zero_energy`): the data said free, the model hung, and the
    lines below 0.5 Hz that a 16 s record adds (the 0.25 Hz line: the model 3.8 times the data at 508+Y) held
    99 % of the nominal χ²: on these three points E_wing went to 0.99868 (−0.13 %); on five points
    (+218+Z, 600+Z) and on the 13 of the issue, a 'spring to ground' at 202+Y / 204+Y of 98-99 N/m was found."""
    from modalab.app.cli import main
    _quiet_hits(tmp_path / "hits.uff", n_samples=32768, points=["208+Z", "508+Y", "100+Z"])
    assert main(["frf", str(tmp_path / "hits.uff"), "-o", str(tmp_path / "frf.uff"), "--no-plot"]) == 0
    params = str(DEMO / "params.toml")
    assert main(["diagnose", str(DEMO / "nominal.bdf"), str(tmp_path / "frf.uff"), "--params", params,
                 "--json", str(tmp_path / "diag.json")]) == 0
    d = json.loads((tmp_path / "diag.json").read_text())
    assert d["findings"] == [], [f["description"] for f in d["findings"]]
    factors = {k: v["updated"] for k, v in d["parameters"].items() if v["mode"] == "factor"}
    assert set(factors) == {"E_wing", "t_wing", "t_fin", "rho_fuselage"}
    assert all(abs(v - 1.0) < 3e-4 for v in factors.values()), factors
    assert main(["identify", str(tmp_path / "frf.uff"), "--band", "5", "700", "-o", str(tmp_path / "modes.uff"),
                 "--json", str(tmp_path / "modes.json")]) == 0
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(tmp_path / "modes.json"), "--params", params,
                 "-o", str(tmp_path / "updated")]) == 0
    up = json.loads((tmp_path / "updated" / "update.json").read_text())
    assert all(abs(v["updated"] - 1.0) < 3e-4 for v in up["parameters"].values()), up["parameters"]
