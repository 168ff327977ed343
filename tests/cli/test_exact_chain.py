"""An exact model stays exact through the documented CLI chain (issue 14 #1-#2).

Hits simulated from ``examples/demo_project/nominal.bdf`` itself (13 roving-hammer points, 3 accelerometers,
the issue's command), then ``frf`` with and without the exponential window, ``identify --band 5 700`` and
``update`` with the demo's parameter file, every step through ``main([...])`` as a user types it.  The data hold
what broke the chain: three FE modes within 0.9 % at 37.3-37.6 Hz that identification returns as one mode
(its shape a mix of them: MAC 0.53 with the nearest FE mode alone), three at 313-314.5 Hz merged into one
mode, and a weakly excited mode at 375 Hz whose shape comes out with MPC 0.64.  Before the fix the update
moved E_wing by +3.6 % and rho_fuselage by +5 %.  The simulated lab's signal chain (hammer, noise,
averaging, H1) and the identification are not the FE code under test; the pairing and the updating are.
"""
import json
from pathlib import Path

import numpy as np
import pytest

from modalab.app.cli import main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo_project"
POINTS = "200+Z 204+Z 208+Z 213+Z 217+Z 218+Z 100+Z 115+Z 308+Z 408+Z 508+Y 600+Z 608+Z".split()
REFS = "218+Z 200+Z 508+Y".split()


@pytest.fixture(scope="module")
def hits(tmp_path_factory):
    d = tmp_path_factory.mktemp("exact_chain")
    assert main(["sim", "--structure", str(DEMO / "nominal.bdf"), "--points", *POINTS, "--references", *REFS,
                 "-o", str(d / "hits.uff"), "--no-plot"]) == 0
    return d / "hits.uff"


@pytest.mark.parametrize("window", [["--exp-end", "0.01"], []], ids=["exp-window", "no-window"])
def test_the_documented_chain_leaves_the_nominal_parameters_at_nominal(hits, tmp_path, window):
    assert main(["frf", str(hits), *window, "-o", str(tmp_path / "frf.uff"), "--no-plot"]) == 0
    assert main(["identify", str(tmp_path / "frf.uff"), "--band", "5", "700", "-o", str(tmp_path / "modes.uff"),
                 "--json", str(tmp_path / "modes.json")]) == 0
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(tmp_path / "modes.json"),
                 "--params", str(DEMO / "params.toml"), "-o", str(tmp_path / "updated")]) == 0
    up = json.loads((tmp_path / "updated" / "update.json").read_text())
    p = {k: v["updated"] for k, v in up["parameters"].items()}
    assert set(p) == {"E_wing", "t_wing", "t_fin", "rho_fuselage"}
    assert all(abs(v - 1.0) < 0.005 for v in p.values()), p
    # exact within the stated uncertainty, and that uncertainty is a tight one (the identification's
    # frequency sigma, 1e-5 of the frequency; raised where the residuals show them optimistic)
    _within_stated_std(up, 3.0, 0.002)
    # the merged 37.5 Hz test mode is reported unpaired, with its reason, and is out of the objective
    before = up["correlation_before"]
    modes = json.loads((tmp_path / "modes.json").read_text())
    f = np.asarray(modes["freq_hz"])
    k = int(np.argmin(np.abs(f - 37.5))) + 1
    assert abs(f[k - 1] - 37.5) < 0.2
    # honest damping: the deck's structural damping (PARAM G 0.02) gives every mode zeta = 1 %; a merged pick
    # refined into a compromise over three modes read 4.4 % at 311.5 Hz before
    assert np.all(np.abs(np.asarray(modes["damping"]) - 0.01) < 0.003), modes["damping"]
    assert k in before["pairing"]["unpaired_test_modes"]
    assert before["pairing"]["unpaired_reason"][str(k)].startswith("merged or ambiguous")
    # every pair the objective kept is a true one: frequency within 0.5 %
    rows = before["pairs"]
    assert len(rows) >= 15 and all(abs(r["freq_error_pct"]) < 0.5 for r in rows), rows


def _within_stated_std(up, k, std_max):
    for name, v in up["parameters"].items():
        assert v["std"] is not None and v["std"] < std_max, (name, v)
        assert abs(v["updated"] - 1.0) <= k * v["std"], (name, v)


@pytest.fixture(scope="module")
def identified(hits, tmp_path_factory):
    """``frf --exp-end 0.01`` and ``identify --band 5 700`` of the exact hits: modes.uff and modes.json."""
    d = tmp_path_factory.mktemp("exact_identified")
    assert main(["frf", str(hits), "--exp-end", "0.01", "-o", str(d / "frf.uff"), "--no-plot"]) == 0
    assert main(["identify", str(d / "frf.uff"), "--band", "5", "700", "-o", str(d / "modes.uff"),
                 "--json", str(d / "modes.json")]) == 0
    return d


def test_update_from_the_uff_takes_the_uncertainties_of_its_identification(identified, tmp_path, capsys):
    """``update --modes modes.uff`` (UFF 55 carries no frequency uncertainty) with the modes.json of the same
    identify run beside it: its freq_std_hz weight the frequencies, said in the output, and the exact model
    stays exact within the stated standard deviations.  Before, the UFF got 1 % weights without saying where
    they came from, and E_wing moved by 1.3 %."""
    capsys.readouterr()
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(identified / "modes.uff"),
                 "--params", str(DEMO / "params.toml"), "-o", str(tmp_path / "u")]) == 0
    out = capsys.readouterr().out
    assert "frequency weights: relative sigma per test mode" in out and "modes.json beside modes.uff" in out, out
    up = json.loads((tmp_path / "u" / "update.json").read_text())
    _within_stated_std(up, 3.0, 0.002)
    # the UFF alone: the 1 % is called an assumption, and the exact model stays within what that states
    (tmp_path / "alone").mkdir()
    (tmp_path / "alone" / "modes.uff").write_bytes((identified / "modes.uff").read_bytes())
    assert main(["update", str(DEMO / "nominal.bdf"), "--modes", str(tmp_path / "alone" / "modes.uff"),
                 "--params", str(DEMO / "params.toml"), "-o", str(tmp_path / "u1")]) == 0
    out = capsys.readouterr().out
    assert "frequency weights: relative sigma 0.01 for every test mode: an assumption" in out, out
    up = json.loads((tmp_path / "u1" / "update.json").read_text())
    _within_stated_std(up, 3.0, 0.05)


def test_the_modes_only_diagnosis_leaves_the_exact_model_alone(hits, tmp_path):
    """``diagnose --modes`` on the same exact data: no finding, parameters at nominal within their stated
    standard deviations' reach.  Before, its own greedy MAC-only pairing took the merged 37.5 Hz mode for
    one FE mode and the shape residual of the 375 Hz mode (MPC 0.64) pulled the parameters: E_wing 1.030,
    t_fin 1.034, rho_fuselage 1.042, and "updating raises the held-out frequency error from 0.0 % to 0.6 %"."""
    assert main(["frf", str(hits), "--exp-end", "0.01", "-o", str(tmp_path / "frf.uff"), "--no-plot"]) == 0
    assert main(["identify", str(tmp_path / "frf.uff"), "--band", "5", "700", "-o", str(tmp_path / "modes.uff"),
                 "--json", str(tmp_path / "modes.json")]) == 0
    assert main(["diagnose", str(DEMO / "nominal.bdf"), "--modes", str(tmp_path / "modes.json"),
                 "--params", str(DEMO / "params.toml"), "--json", str(tmp_path / "diag.json")]) == 0
    d = json.loads((tmp_path / "diag.json").read_text())
    assert d["findings"] == []
    p = {k: v["updated"] for k, v in d["parameters"].items()}
    assert all(abs(v - 1.0) < 0.005 for v in p.values()), p


def test_the_frf_diagnosis_leaves_the_exact_model_at_nominal(identified, tmp_path, caplog):
    """``diagnose nominal.bdf frf.uff`` on the exact, exponentially windowed FRFs of the issue's chain: no
    finding, and every E and ρ within 0.4 % and 5 of its stated standard deviations of nominal (measured:
    +0.07 to +0.18 %, at most 3.5 std; +0.05 to +0.23 % while the force window cut the AC coupling's
    undershoot).  Before the simulated lab's missed hits were an eccentric force, they leaned on the
    neighbouring node, the FRFs read about 1 % low and all E and ρ rose together by +1.1 % (30-45 std; issue
    14 #2).  What remains is the lab's 3 mm placement scatter: its misses read the FRFs 0.65 % low at
    80-150 Hz (0.1-0.2 % elsewhere) for this seed; with it off they match the structure within 0.01 %."""
    with caplog.at_level("WARNING", logger="updating.diagnosis.fit"):
        assert main(["diagnose", str(DEMO / "nominal.bdf"), str(identified / "frf.uff"),
                     "--json", str(tmp_path / "diag.json")]) == 0
    assert not [r for r in caplog.records if "leakage" in r.getMessage()]
    d = json.loads((tmp_path / "diag.json").read_text())
    assert d["findings"] == []
    for name, v in d["parameters"].items():
        if v["mode"] == "factor":
            assert abs(v["updated"] - 1.0) < 0.004 and abs(v["updated"] - 1.0) < 5 * v["std"], (name, v)


@pytest.mark.slow
def test_the_frf_diagnosis_of_unwindowed_data_warns_of_the_leakage(hits, tmp_path, caplog):
    """The same exact data without the window: the bungee and first elastic modes (ζ = 1 %) outlive the 4 s
    record, 25 % leakage below 14 Hz: the diagnosis says so and how to measure instead; no finding either way,
    and every E and ρ within 0.3 % and 6 std of nominal (measured +0.07 to +0.15 %, at most 3.1 std: the lab's
    placement scatter, as with the window above).  Before the cut tails were restored
    (:mod:`updating.diagnosis.truncation`) −0.04 to −0.25 %, at most 4.8 std: the leakage, −0.14 to −0.27 %
    (3.5-7.6 std) on the same chain without noise and placement scatter, −0.001 to +0.005 % now
    (tests/updating/test_diagnosis_truncation.py).  Before that, E and ρ rose together by +0.42 to +0.62 %
    (8-11 std): the force window cut the IEPE coupling's undershoot (0.5 Hz corner) from the force while the
    responses kept it, which read the FRFs +16..+22 % off at 0.1-2 Hz and −4 % at 2-5 Hz
    (:func:`acquisition.windows.windowed_force`)."""
    assert main(["frf", str(hits), "-o", str(tmp_path / "frf.uff"), "--no-plot"]) == 0
    with caplog.at_level("WARNING", logger="updating.diagnosis.fit"):
        assert main(["diagnose", str(DEMO / "nominal.bdf"), str(tmp_path / "frf.uff"),
                     "--json", str(tmp_path / "diag.json")]) == 0
    said = [r.getMessage() for r in caplog.records if "leakage of up to" in r.getMessage()]
    assert len(said) == 1 and "outlive the 4 s record" in said[0] and "--exp-end" in said[0], said
    d = json.loads((tmp_path / "diag.json").read_text())
    assert d["findings"] == []
    for name, v in d["parameters"].items():
        if v["mode"] == "factor":
            assert abs(v["updated"] - 1.0) < 0.003 and abs(v["updated"] - 1.0) < 6 * v["std"], (name, v)
