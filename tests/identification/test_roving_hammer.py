"""Issue 16, items 1-3: a roving-hammer analyser export (3 accelerometers x 74 hammer points).

The data come from ``roving_lab`` (a generator of its own: plate modes, H1-consistent noise and
coherence, an exponential window applied as the analyser does).  Targets: the export identified in
either orientation with the 0.3 % close pair separated and the single-reference mode kept, every
mode found, no spurious mode, the same result on repeated runs; the window correction from the
file or from the option, said in the output.
"""
import json

import numpy as np
import pytest

from identification import identify
from identification.api import resolve_window, roving_hammer_layout
from modalab.app.cli import main
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF
from roving_lab import ACCEL_POINTS, BETA, PAIR, SINGLE, roving_hammer_export


def _export(beta_in_file=True, **kw):
    d = roving_hammer_export(**kw)
    frf = FRF(freq_hz=d["freq_hz"], H=d["H"], responses=d["responses"], references=d["references"],
              coherence=d["coherence"], window_beta_per_s=d["beta"] if beta_in_file else 0.0,
              metadata={"estimator": "H1", "n_averages": d["n_averages"]})
    return frf, d


def _check_modes(modes, d, ftol=5e-4, ztol=0.05):
    fn, zeta = d["modes"]["freq_hz"], d["modes"]["damping"]
    assert modes.n_modes == fn.size, f"found {np.round(modes.freq_hz, 3)}; expected {fn}"
    np.testing.assert_allclose(modes.freq_hz, fn, rtol=ftol)
    np.testing.assert_allclose(modes.damping, zeta, rtol=ztol)


@pytest.fixture(scope="module")
def export():
    return _export(seed=0)


@pytest.fixture(scope="module")
def identified(export):
    frf, d = export
    return identify(frf)


def test_roving_layout_is_recognised_and_transposed(export, identified, caplog):
    frf, d = export
    assert roving_hammer_layout(frf) and not roving_hammer_layout(frf.transpose())
    modes, report = identified
    rc = report.settings["reciprocity"]
    assert rc["applied"] and rc["measured_shape"] == [3, 74] and "roving-hammer" in rc["reason"]
    assert [str(r) for r in modes.references] == [f"{p + 1}+Z" for p in ACCEL_POINTS]
    assert modes.shapes.shape == (74, 13)
    _check_modes(modes, d)


def test_either_orientation_gives_the_same_modes(export, identified):
    frf, d = export
    modes, _ = identified
    again, rep = identify(frf.transpose())             # already in reciprocity order: nothing to transpose
    assert not rep.settings["reciprocity"]["applied"]
    np.testing.assert_array_equal(again.freq_hz, modes.freq_hz)
    np.testing.assert_array_equal(again.damping, modes.damping)
    # repeated runs: the same modes, bit for bit
    third, _ = identify(frf)
    np.testing.assert_array_equal(third.freq_hz, modes.freq_hz)
    np.testing.assert_array_equal(third.shapes, modes.shapes)


def test_close_pair_and_single_reference_mode(identified, export):
    _, d = export
    modes, report = identified
    fn = d["modes"]["freq_hz"]
    pair = modes.select_modes((modes.freq_hz > 124.5) & (modes.freq_hz < 126.5))
    assert pair.n_modes == 2
    np.testing.assert_allclose(pair.freq_hz, fn[list(PAIR)], rtol=2e-4)
    # the pair's shapes are distinct modes, not one mode twice
    from identification import mac_vectors
    assert mac_vectors(pair.shapes[:, :1], pair.shapes[:, 1:])[0, 0] < 0.5
    # the mode seen by one accelerometer only: kept, with its own damping
    single = modes.select_modes(np.abs(modes.freq_hz - fn[SINGLE]) < 0.2)
    assert single.n_modes == 1
    np.testing.assert_allclose(single.damping, d["modes"]["damping"][SINGLE], rtol=0.05)
    part = np.abs(single.participation[:, 0])
    assert part[0] > 20 * max(part[1], part[2])
    assert np.all(report.frf_correlation > 0.95)


@pytest.mark.parametrize("seed", [1, 2])
def test_close_pair_with_alike_participation(seed):
    """Participation MAC ~0.9 between the pair: they are still two modes because they coexist order by order."""
    frf, d = _export(seed=seed, pair="alike", single_amp=0.12)
    modes, _ = identify(frf, band_hz=(95.0, 165.0))
    inband = (d["modes"]["freq_hz"] > 96) & (d["modes"]["freq_hz"] < 164)
    sub = {"modes": {k: v[inband] for k, v in d["modes"].items()}}
    _check_modes(modes, sub)


def test_reciprocity_forced_and_refused(export):
    frf, d = export
    small = frf.select(references=frf.references[:5]).band(95.0, 165.0)     # 3 x 5: not a roving layout
    assert not roving_hammer_layout(small)
    _, rep = identify(small, reciprocity=True, max_order=12)
    assert rep.settings["reciprocity"]["applied"] and rep.settings["reciprocity"]["reason"] == "forced"
    assert rep.settings["references"] == [str(x) for x in small.responses]
    _, rep = identify(small, reciprocity=False, max_order=12)
    assert not rep.settings["reciprocity"]["applied"]
    with pytest.raises(ModalabValueError, match="reciprocity"):
        identify(small, reciprocity="yes")


class TestWindowCorrection:
    def test_resolve(self, export):
        frf, _ = export
        bare = frf._replace(window_beta_per_s=0.0)
        assert resolve_window(frf) == (BETA, "file")
        assert resolve_window(bare) == (0.0, "none")
        assert resolve_window(bare, 0.2) == (0.2, "option")
        assert resolve_window(frf, BETA) == (BETA, "file")
        with pytest.raises(ModalabValueError, match="--force-window"):
            resolve_window(frf, 0.2)
        b, src = resolve_window(frf, 0.2, force=True)
        assert b == 0.2 and "overrides the file's beta=0.139" in src
        with pytest.raises(ModalabValueError, match="needs exp_beta"):
            resolve_window(frf, force=True)
        with pytest.raises(ModalabValueError, match="exp_beta"):
            resolve_window(bare, -1.0)

    def test_damping_drops_by_beta_over_omega(self, export, identified):
        frf, d = export
        modes, _ = identified
        raw, rep = identify(frf._replace(window_beta_per_s=0.0), band_hz=(10.0, 60.0))
        assert rep.settings["window_correction"] == {"beta_per_s": 0.0, "source": "none"}
        by_opt, rep = identify(frf._replace(window_beta_per_s=0.0), band_hz=(10.0, 60.0), exp_beta=BETA)
        assert rep.settings["window_correction"] == {"beta_per_s": BETA, "source": "option"}
        k = np.argmin(np.abs(raw.freq_hz - 18.4))
        drop = raw.damping[k] - by_opt.damping[k]
        np.testing.assert_allclose(drop, BETA / (2 * np.pi * raw.freq_hz[k]), rtol=0.01)
        np.testing.assert_allclose(by_opt.damping[k], d["modes"]["damping"][0], rtol=0.02)
        np.testing.assert_allclose(by_opt.damping[k], modes.damping[0], rtol=1e-3)


def test_cli_roving_export_with_exp_beta(tmp_path, capsys):
    """``modalab identify`` on the analyser export written as UFF without beta: --exp-beta corrects,
    the output says the file was transposed and which correction was applied."""
    frf, d = _export(beta_in_file=False, seed=3)
    frf = frf.band(95.0, 165.0)
    p = tmp_path / "export.uff"
    frf.to_uff(p)
    out_json = tmp_path / "m.json"
    assert main(["identify", str(p), "-o", str(tmp_path / "m.uff"), "--json", str(out_json),
                 "--exp-beta", str(BETA)]) == 0
    txt = capsys.readouterr().out
    assert "reciprocity: 3 responses x 74 references looks like a roving-hammer export" in txt
    assert f"beta = {BETA:g} 1/s from the --exp-beta" in txt
    js = json.loads(out_json.read_text())
    assert js["window_correction"] == {"beta_per_s": BETA, "source": "option"}
    assert js["reciprocity"]["applied"] is True
    fn = np.array(js["freq_hz"])                     # modes.json: the ModeSet at the top level (its schema)
    inband = d["modes"]["freq_hz"][(d["modes"]["freq_hz"] > 96) & (d["modes"]["freq_hz"] < 164)]
    np.testing.assert_allclose(fn, inband, rtol=5e-4)
    # a beta in the file and a different --exp-beta: refused (exit 2, one line), accepted with --force-window
    frf._replace(window_beta_per_s=0.5).to_uff(tmp_path / "b.uff")
    assert main(["identify", str(tmp_path / "b.uff"), "-o", str(tmp_path / "n.uff"), "--exp-beta", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "--force-window" in err and "Traceback" not in err
    assert not (tmp_path / "n.uff").exists()
    assert main(["identify", str(tmp_path / "b.uff"), "-o", str(tmp_path / "n.uff"), "--exp-beta", "0.2",
                 "--force-window"]) == 0
    assert "overrides the file's beta=0.5" in capsys.readouterr().out
    # --no-reciprocity: identified as given, and said so
    frf.select(references=frf.references[:8]).to_uff(tmp_path / "c.uff")
    assert main(["identify", str(tmp_path / "c.uff"), "-o", str(tmp_path / "c_modes.uff"), "--no-reciprocity",
                 "--max-order", "10", "--select", "125.2,125.6"]) == 0
    txt = capsys.readouterr().out
    assert "reciprocity refused: 3 responses x 8 references identified as given" in txt
