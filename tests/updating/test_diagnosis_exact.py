"""An exact model stays exact (BRIEF; issue 13, issue 14 #1-2): FRFs measured through the simulated lab
(hammer, IEPE chain, anti-alias filter, ADC, H1 from 3 hits) on a structure built from the nominal bulk data
itself give no finding and leave the parameters at nominal within their uncertainty, with and without the
exponential window."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from modalab.core import uff
from modalab.app.stages import FRFOptions, SimOptions, frf, sim
from updating.fe.bulk import build_model, read_bdf
from updating.diagnosis import diagnose

NOMINAL = Path(__file__).resolve().parents[2] / "examples" / "concealed" / "bar_control" / "nominal.bdf"


@pytest.fixture(scope="module")
def hits(tmp_path_factory):
    d = tmp_path_factory.mktemp("exact")
    sim(d / "hits.uff", SimOptions(structure=str(NOMINAL), points=[f"{i}+Z" for i in range(1, 10)],
                                   references=["3+Z", "8+Z"], seed=3, sample_rate_hz=1024.0, n_samples=4096))
    return d


@pytest.mark.parametrize("exp_end", [0.01, None])
def test_data_simulated_from_the_nominal_give_no_finding(hits, exp_end, caplog):
    out = hits / f"frf_{exp_end}.uff"
    frf(hits / "hits.uff", out, FRFOptions(exp_end_level=exp_end))
    model = build_model(read_bdf(NOMINAL))
    with caplog.at_level("WARNING", logger="updating.diagnosis.fit"):
        d = diagnose(model, uff.read_frf(out), max_lines=120)
    # its modes on the springs (2.25 and 4.04 Hz, ζ = 1 %) keep 57 % and 36 % of their amplitude at the end of
    # the 4 s record: said once without the window (fit.decay_leakage), not with it (0.5 %)
    said = [r.getMessage() for r in caplog.records if "leakage of up to" in r.getMessage()]
    assert len(said) == (0 if exp_end else 1), said
    dd = d.to_dict()
    assert dd["findings"] == [], dd["findings"]
    par = dd["parameters"]
    # every parameter at nominal within its printed uncertainty: before the simulated lab's miss was an
    # eccentric force (it leaned the force on the neighbouring node 0.2 m away), the chain read 1.35 % low and
    # E and ρ rose together by 1.3 % at 30-45 σ (issue 14 #2)
    for name, p in par.items():
        if p["mode"] == "factor":
            assert abs(p["updated"] - 1.0) < max(4 * p["std"], 1e-3), (name, p)
            assert p["updated"] == pytest.approx(1.0, abs=3e-3), (name, p)
    assert dd["parameters"]["eta_global"]["updated"] == pytest.approx(0.02, rel=0.05)
    for blk in dd["fit"].values():
        assert blk["freq_error_max_pct"] < 1.0 and blk["mac_min"] > 0.95 and blk["n_pairs"] >= 3
    # χ²/N of the final model in units of the data's noise model (coherence, averages, leakage bounds, 1 % floor):
    # measured 0.34 (training) / 0.37 (held-out) with the exponential window, 0.24 / 0.30 without it (0.39 / 0.42
    # before the record's cut tails were restored, updating.diagnosis.truncation: E and ρ −0.047 ± 0.059 %, now
    # −0.038 ± 0.021 %); below 1
    # because the 1 % floor exceeds the simulated lab's errors (1.40 / 0.91 with the window while the lab's
    # miss read the FRFs 1.35 % low)
    chi2 = [dd["fit"]["with_physics"][f"chi2_per_value_{k}"] for k in ("train", "held_out")]
    assert all(0.2 <= c <= 1.5 for c in chi2), chi2
