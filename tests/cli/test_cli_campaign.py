"""Campaign mode from the command line (README: ``identify``/``diagnose`` take many inputs, local processes or
``--dask``): the results are those of serial single-file runs, file by file."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from modalab.core import uff
from modalab.app.cli import main
from modalab.app.outputs import validate

CASES = Path(__file__).resolve().parents[2] / "examples" / "concealed"


def _frf_files(tmp_path, n=2):
    from identification.synthetic import modal_system, noisy_frf

    paths = []
    f = np.linspace(1.0, 100.0, 400)
    for k in range(n):
        model, _ = modal_system(np.array([20.0, 45.0, 70.0]) * (1 + 0.02 * k), [0.01, 0.015, 0.01], n_dof=6, rng=k)
        p = tmp_path / f"config_{k}.uff"
        uff.write_frf(p, noisy_frf(model, f, references=["1+Z", "4+Z"], noise=0.002, rng=k))
        paths.append(p)
    return paths


def test_identify_campaign_equals_serial_runs(tmp_path, capsys):
    paths = _frf_files(tmp_path)
    camp = tmp_path / "camp"
    assert main(["identify", *map(str, paths), "--band", "5", "95", "--max-order", "12", "-o", str(camp),
                 "--workers", "2"]) == 0
    index = json.loads((camp / "campaign.json").read_text())
    assert [r["input"] for r in index] == [str(p.resolve()) for p in paths]
    for k, p in enumerate(paths):
        one = tmp_path / f"serial_{k}.json"
        assert main(["identify", str(p), "--band", "5", "95", "--max-order", "12", "-o",
                     str(tmp_path / f"serial_{k}.uff"), "--json", str(one)]) == 0
        serial, pooled = json.loads(one.read_text()), json.loads((camp / p.stem / "modes.json").read_text())
        validate(pooled, "modes")
        assert pooled["freq_hz"] == serial["freq_hz"] and pooled["shapes"] == serial["shapes"]
        np.testing.assert_allclose(sorted(serial["freq_hz"])[:3], np.array([20.0, 45.0, 70.0]) * (1 + 0.02 * k),
                                   rtol=2e-3)
    assert "campaign index" in capsys.readouterr().out


def test_diagnose_campaign_on_a_dask_cluster_equals_serial_runs(tmp_path):
    distributed = pytest.importorskip("distributed")
    model = CASES / "bar_added_mass" / "nominal.bdf"
    inputs = []
    for case in ("bar_added_mass", "bar_control"):           # two configurations of one structure
        inputs.append(tmp_path / f"{case}.uff")
        shutil.copyfile(CASES / case / "measured.uff", inputs[-1])
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        assert main(["diagnose", str(model), *map(str, inputs), "--report", str(tmp_path / "camp"),
                     "--dask", cluster.scheduler_address]) == 0
    finally:
        cluster.close()
    for p in inputs:
        assert main(["diagnose", str(model), str(p), "--json", str(tmp_path / f"{p.stem}.json")]) == 0
        serial = json.loads((tmp_path / f"{p.stem}.json").read_text())
        remote = json.loads((tmp_path / "camp" / p.stem / "diagnosis.json").read_text())
        validate(remote, "diagnosis")
        for d in (serial, remote):
            d.pop("timings_s")
        assert remote == serial
    found = {p.stem: json.loads((tmp_path / "camp" / p.stem / "diagnosis.json").read_text())["findings"]
             for p in inputs}
    assert [f["physics"] for f in found["bar_added_mass"]] == ["added_mass"] and found["bar_control"] == []


def test_diagnose_campaign_needs_a_report_folder(tmp_path, capsys):
    m = str(CASES / "bar_control" / "nominal.bdf")
    f = str(CASES / "bar_control" / "measured.uff")
    assert main(["diagnose", m, f, f, "--json", str(tmp_path / "d.json")]) == 2
    assert "--report FOLDER" in capsys.readouterr().err
    assert not (tmp_path / "d.json").exists()
