"""Campaigns: the same results serially, on a local process pool and on a Dask cluster."""
from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from modalab.core import uff
from modalab.app.campaign import CampaignError, identify_many, run_many
from modalab.core.errors import ModalabValueError
from modalab.app.stages import IdentifyOptions


def _eigs(seed: int) -> list:
    """A deterministic numerical job: natural frequencies of a random spring-mass chain."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(1e3, 2e3, 8)
    m = rng.uniform(0.5, 1.5, 8)
    K = np.diag(k + np.r_[k[1:], 0]) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    from scipy.linalg import eigh

    w2 = eigh(K, np.diag(m), eigvals_only=True)
    return list(np.sqrt(w2) / (2 * np.pi))


def _fail_on_three(x):
    if x == 3:
        raise ValueError("three is bad")
    return x * 2


def _closed_form(a, x):
    return a * x ** 2


def test_serial_and_process_pool_agree():
    inputs = list(range(6))
    serial = run_many(_eigs, inputs, workers=1)
    pooled = run_many(_eigs, inputs, workers=2)
    assert pooled == serial                      # bit-identical, in input order
    assert len(serial) == 6 and all(len(r) == 8 for r in serial)
    # the 1-DOF closed form through a partial: order kept
    assert run_many(functools.partial(_closed_form, 3.0), [1, 2, 5], workers=2) == [3.0, 12.0, 75.0]


def test_failures_name_the_input():
    with pytest.raises(CampaignError, match=r"1 of 5 .*input 3.*three is bad"):
        run_many(_fail_on_three, range(5), workers=1)
    out = run_many(_fail_on_three, range(5), workers=2, errors="collect")
    assert out[:3] == [0, 2, 4] and isinstance(out[3], ValueError) and out[4] == 8
    with pytest.raises(ModalabValueError, match="workers"):
        run_many(_eigs, [1], workers=0)
    with pytest.raises(ModalabValueError, match="scheduler address"):
        pytest.importorskip("distributed")
        run_many(_eigs, [1], dask="localhost")


def _synthetic_frf_files(tmp_path, n=2):
    from identification.synthetic import modal_system, noisy_frf

    paths = []
    f = np.linspace(1.0, 100.0, 400)
    for k in range(n):
        fn = np.array([20.0, 45.0, 70.0]) * (1 + 0.02 * k)
        model, _ = modal_system(fn, [0.01, 0.015, 0.01], n_dof=6, rng=k)
        frf = noisy_frf(model, f, references=["1+Z", "4+Z"], noise=0.002, rng=k)
        p = tmp_path / f"config_{k}.uff"
        uff.write_frf(p, frf)
        paths.append(p)
    return paths


def test_identify_many_same_results_serial_and_parallel(tmp_path):
    paths = _synthetic_frf_files(tmp_path)
    a = identify_many(paths, tmp_path / "serial", IdentifyOptions(max_order=12), plots=False, workers=1)
    b = identify_many(paths, tmp_path / "pool", IdentifyOptions(max_order=12), plots=False, workers=2)
    fa = [r["freq_hz"] for r in a]
    assert fa == [r["freq_hz"] for r in b]
    for k, f in enumerate(fa):              # and right: the synthetic modes
        np.testing.assert_allclose(sorted(f)[:3], np.array([20.0, 45.0, 70.0]) * (1 + 0.02 * k), rtol=2e-3)
    idx = json.loads((tmp_path / "pool" / "campaign.json").read_text())
    assert [r["input"] for r in idx] == [str(p.resolve()) for p in paths]
    assert (tmp_path / "pool" / "config_1" / "modes.uff").is_file()


def test_dask_local_cluster_gives_the_serial_results(tmp_path):
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        addr = cluster.scheduler_address
        assert addr.startswith("tcp://")
        inputs = list(range(5))
        assert run_many(_eigs, inputs, dask=addr) == run_many(_eigs, inputs, workers=1)
        paths = _synthetic_frf_files(tmp_path)
        a = identify_many(paths, tmp_path / "serial", IdentifyOptions(max_order=12), plots=False, workers=1)
        b = identify_many(paths, tmp_path / "dask", IdentifyOptions(max_order=12), plots=False, dask=addr)
        assert [r["freq_hz"] for r in a] == [r["freq_hz"] for r in b]
        with pytest.raises(CampaignError, match="three is bad"):
            run_many(_fail_on_three, range(5), dask=addr)
    finally:
        cluster.close()
