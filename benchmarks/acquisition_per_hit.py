"""Benchmark: processing one hammer hit of a 32-channel, 10 s record, against the record length.

Run ``python benchmarks/acquisition_per_hit.py [--channels 32] [--seconds 10] [--fs 8192] [--hits 5]``.

What the session does with every hit (``acquisition.session.AcquisitionSession``), timed stage by stage:

* checks   — :func:`acquisition.checks.check_hit` (double hit, overload, trigger, decay, pretrigger)
             and the session's dead-channel test;
* FRF      — :meth:`acquisition.spectral.SpectralAverager.add` (windows + one FFT per channel + cross
             spectra) and ``frf()`` limited to the analysis band (the running H1 and coherence);
* preview  — the arrays the observer draws: force spectrum in dB, |H| in dB and coherence of every channel;
* store    — :meth:`acquisition.store.HitStore.add` (npz, fsync of file and directory, journal line, fsync),
             reported separately because it depends on the disk.

The records are a force half-sine (0.8 ms) and 31 responses, each a sum of decaying modes of the
same hit plus noise, in engineering units.  The ratio printed is the processing time of one hit over
the record length: below 1 the session keeps up with the bench (the operator waits for the record to
end anyway); "well under" means the ratio should be a few per cent.
"""
from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np


def make_hit(rng, n_ch: int, fs: float, n: int, pre: int, hit_id: int):
    from modalab.core.records import TimeRecord

    t = (np.arange(n) - pre) / fs
    width = 0.8e-3
    f = np.where((t >= 0) & (t <= width), 100.0 * np.sin(np.pi * np.clip(t, 0, width) / width), 0.0)
    f += rng.normal(0, 0.02, n)
    freqs = np.array([19.0, 67.5, 71.0, 118.4, 203.4, 216.5, 268.9, 437.2, 582.2, 911.0, 1430.0, 2100.0])
    zeta = 0.005 + 0.01 * freqs / 1000
    tp = np.maximum(t, 0)
    modes = np.exp(-zeta[:, None] * 2 * np.pi * freqs[:, None] * tp) * np.sin(2 * np.pi * freqs[:, None] * tp)
    amps = rng.normal(0, 20.0, (n_ch - 1, freqs.size))
    y = amps @ modes * (t >= 0) + rng.normal(0, 0.01, (n_ch - 1, n))
    data = np.vstack([f, y])
    dofs = ["4+Z"] + [f"{100 + i}+Z" for i in range(n_ch - 1)]
    roles = ["force"] + ["response"] * (n_ch - 1)
    units = ["N"] + ["m/s^2"] * (n_ch - 1)
    return TimeRecord(sample_rate_hz=fs, data=data, dofs=dofs, roles=roles, units=units,
                      sensitivity=np.r_[2.25e-3, np.full(n_ch - 1, 5.1e-3)], trigger_index=pre,
                      overload=np.zeros(n_ch, bool), hit_id=hit_id, metadata={})


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--channels", type=int, default=32, help="channels (1 force + responses)")
    ap.add_argument("--seconds", type=float, default=10.0, help="record length in s")
    ap.add_argument("--fs", type=float, default=8192.0, help="sample rate in Hz (bandwidth = fs/2.56)")
    ap.add_argument("--hits", type=int, default=5, help="hits averaged (each one timed)")
    args = ap.parse_args(argv)

    from acquisition.checks import check_hit
    from acquisition.session import _dead_channels
    from acquisition.spectral import SpectralAverager
    from acquisition.store import HitStore
    from acquisition.windows import ExponentialWindow, ForceWindow

    fs, n = args.fs, int(round(args.seconds * args.fs))
    pre = int(0.01 * n)
    bw = fs / 2.56
    rng = np.random.default_rng(1)
    hits = [make_hit(rng, args.channels, fs, n, pre, k + 1) for k in range(args.hits)]
    ranges = [2000.0] + [981.0] * (args.channels - 1)
    avg = SpectralAverager(force_window=ForceWindow(fraction=0.05), exp_window=ExponentialWindow(end_level=0.01))
    times = {"checks": [], "FRF": [], "preview": [], "store": []}
    with tempfile.TemporaryDirectory() as tmp:
        store = HitStore(tmp)
        for rec in hits:
            t0 = time.perf_counter()
            report = check_hit(rec, ranges=ranges, trigger_level=5.0)
            _dead_channels(rec)
            t1 = time.perf_counter()
            avg.add(rec)
            frf = avg.frf().band(0.0, bw)
            t2 = time.perf_counter()
            fi = rec.force_channels[0]
            F = np.abs(np.fft.rfft(rec.data[fi])) / fs
            preview = (20 * np.log10(np.maximum(F, 1e-300) / F[1:50].max()),
                       20 * np.log10(np.maximum(np.abs(frf.H[:, 0]), 1e-300)), frf.coherence[:, 0])
            t3 = time.perf_counter()
            store.add(rec, point=0, status="candidate")
            t4 = time.perf_counter()
            for k, dt in zip(times, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
                times[k].append(dt)
            del report, preview
    rec_s = n / fs
    print(f"one hit: {args.channels} channels x {n} samples ({rec_s:g} s at {fs:g} Hz), "
          f"{frf.n_freq} lines to {bw:g} Hz, median of {args.hits} hits")
    proc = 0.0
    for k, v in times.items():
        m = float(np.median(v))
        if k != "store":
            proc += m
        print(f"  {k:>8}: {1e3 * m:8.1f} ms   ratio to the record length {m / rec_s:.4f}")
    print(f"  processing (checks + FRF + preview): {1e3 * proc:.1f} ms per hit; "
          f"ratio to the record length {proc / rec_s:.4f} ({100 * proc / rec_s:.2f} %)")
    tot = proc + float(np.median(times["store"]))
    print(f"  with the fsync-ed store: {1e3 * tot:.1f} ms per hit; ratio {tot / rec_s:.4f}")
    return proc / rec_s


if __name__ == "__main__":
    main()
