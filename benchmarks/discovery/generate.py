"""Generate the concealed-physics cases of the discovery benchmark (issue 13).

    python benchmarks/discovery/generate.py --seeds even --out /tmp/discovery      # tuning half
    python benchmarks/discovery/generate.py --seeds odd --out /tmp/discovery       # held-out half
    python benchmarks/discovery/generate.py --seeds 0-59 --out DIR --jobs 2

Each case directory holds ``nominal.bdf``, ``params.toml`` and ``measured.uff`` (the inputs of ``modalab
diagnose``) and ``truth.json`` (what was concealed: only the scorer reads it).  Same seed -> byte-identical
files.  The truth is simulated by ``truthsim.py`` (numpy/scipy only; see README.md).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    __package__ = "benchmarks.discovery"

from benchmarks.discovery.cases import make_case, build_truth          # noqa: E402
from benchmarks.discovery.writers import write_bdf, write_params, write_truth, write_uff   # noqa: E402

N_CASES = 60


def parse_seeds(spec: str, n: int = N_CASES) -> list:
    """'even', 'odd', 'all' (of 0..n-1), '3', '0-9', '1,5,7'."""
    if spec in ("even", "odd", "all"):
        r = range(n)
        return [s for s in r if spec == "all" or (s % 2 == 0) == (spec == "even")]
    out = []
    for part in spec.split(","):
        if "-" in part:
            a, b = part.split("-")
            out += list(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


def simulate(case):
    """Truth accelerance at the hit x sensor DOFs, then H1 and coherence of a 5-average roving-hammer test.

    Each hit gives a force spectrum (half-sine pulse of a hammer tip, amplitude and timing varying from hit to
    hit); every accelerometer records H*F plus noise (complex Gaussian, ``case.noise`` times the RMS of that
    record over the band, as with the input range set for each hit; at least 1e-3 of the channel's largest RMS,
    so that a pair the structure does not couple, e.g. in-plane hit / out-of-plane sensor, reads as noise).  H1 = sum(Y F*) / sum(|F|^2), coherence
    |sum(Y F*)|^2 / (sum|F|^2 sum|Y|^2) over the averages.  Returned rows = hits (by reciprocity).
    """
    rng = np.random.default_rng(10_000 + case.seed)
    nl = case.n_lines
    fmax = case.band_hz[1]
    f = fmax * np.arange(1, nl + 1) / nl
    t = build_truth(case.frame, case.refine, case.errors, case.eta, case.physics)
    X = t.receptance(f, [(n, abs(d)) for n, d in case.hits], [(n, abs(d)) for n, d in case.sensors])
    sh = np.array([np.sign(d) for _, d in case.hits], float)
    ss = np.array([np.sign(d) for _, d in case.sensors], float)
    A = -(2 * np.pi * f) ** 2 * X * sh[:, None, None] * ss[None, :, None]        # accelerance, signed DOFs
    tau = rng.uniform(0.3, 0.45) / fmax          # half-sine pulse; at fmax still above ~ -6 dB (first zero 1.5/tau)
    shape = np.cos(np.pi * f * tau) / (1 - (2 * f * tau) ** 2)
    n_hit = A.shape[0]
    amp = 200.0 * (1 + 0.15 * rng.standard_normal((n_hit, case.n_avg)))
    t0 = rng.uniform(0.0, 0.002, (n_hit, case.n_avg))
    F = amp[:, :, None] * shape * np.exp(-2j * np.pi * f * t0[:, :, None])          # (hit, avg, line)
    Y = A[:, :, None, :] * F[:, None, :, :]                                        # (hit, sensor, avg, line)
    rms = np.sqrt(np.mean(np.abs(Y) ** 2, axis=(2, 3)))                           # per hit and channel
    rms = np.maximum(rms, 1e-3 * rms.max(axis=0, keepdims=True))     # a floor for pairs with no coupling
    N = (rng.standard_normal(Y.shape) + 1j * rng.standard_normal(Y.shape)) / np.sqrt(2)
    Y = Y + case.noise * rms[:, :, None, None] * N
    Sfx = np.sum(Y * np.conj(F)[:, None], axis=2)
    Sff = np.sum(np.abs(F) ** 2, axis=1)[:, None, :]
    Sxx = np.sum(np.abs(Y) ** 2, axis=2)
    H1 = Sfx / Sff
    coh = np.abs(Sfx) ** 2 / (Sff * Sxx)
    return f, A, H1, coh


def write_case(case, out: Path, sim) -> Path:
    """Write the four files of ``case`` from its simulated test ``sim`` = simulate(case); returns the folder."""
    f, A, H1, coh = sim
    d = Path(out) / case.name
    d.mkdir(parents=True, exist_ok=True)
    write_bdf(case, d / "nominal.bdf")
    write_params(case, d / "params.toml")
    write_uff(case, f, H1, coh, d / "measured.uff")
    g = np.clip(coh, 1e-12, 1.0)
    rnd = np.sqrt((1 - g) / (2 * case.n_avg * g))               # random error of H1 from the coherence
    extra = {"median_random_error_from_coherence": float(np.round(np.median(rnd), 6)),
             "median_coherence": float(np.round(np.median(coh), 6))}
    write_truth(case, d / "truth.json", extra)
    return d


def generate_one(seed: int, out: Path) -> dict:
    t0 = time.perf_counter()
    case = make_case(seed)
    d = write_case(case, out, simulate(case))
    return {"seed": seed, "case": case.name, "kind": case.physics["physics"] if case.physics else "control",
            "seconds": time.perf_counter() - t0, "dir": str(d)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="even", help="even | odd | all | 0-9 | 1,3,5 (default: even)")
    ap.add_argument("--n", type=int, default=N_CASES, help="number of cases for even/odd/all (default 60)")
    ap.add_argument("--out", required=True, help="output folder (one sub-folder per case)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    a = ap.parse_args(argv)
    seeds = parse_seeds(a.seeds, a.n)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(a.jobs) as ex:
            results = list(ex.map(generate_one, seeds, [out] * len(seeds)))
    else:
        results = []
        for s in seeds:
            results.append(generate_one(s, out))
            r = results[-1]
            print(f"{r['case']:<32} {r['kind']:<22} {r['seconds']:6.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
