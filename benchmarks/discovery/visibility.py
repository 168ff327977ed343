"""How far above the measurement noise each case's concealed effect shows in its measured FRFs.

    python benchmarks/discovery/visibility.py /tmp/disc          # writes visibility.json into every case folder

A concealed effect can be invisible to a case's sensor layout: a spring in Z on a planar frame measured and hit
only in its plane, a joint released about an axis no sensor and no hit excites.  No diagnosis can name such an
effect, and a score that counts it as a miss mixes two questions.  This script answers the first one from the
**truth simulator alone** (``cases.make_case`` and ``cases.build_truth``, never modalab's own code): the truth's
accelerance at the case's hits x sensors is computed with and without the effect (same seeded case, same
parameter errors and damping), and the change is compared with the noise of the simulated test
(``generate.simulate``: ``case.noise`` times the RMS of each record, with its floor, averaged over
``case.n_avg`` hits):

    chi2_per_value = mean over hits, sensors and lines of |A_with - A_without|^2 / sigma^2

``effect_to_noise`` = sqrt(chi2_per_value).  Below 1 the effect changes the measured FRFs by less than one
noise standard deviation per value on average: :mod:`score` reports the right-finding rate with and without
such cases (both numbers, never one instead of the other).  The threshold is a statement about the data, not
tuned on any diagnosis result.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    __package__ = "benchmarks.discovery"

from benchmarks.discovery.cases import build_truth, make_case        # noqa: E402

NAME = "visibility.json"


def effect_to_noise(seed: int) -> dict:
    """The concealed effect of case ``seed`` against the simulated test's noise (see the module docstring)."""
    case = make_case(seed)
    if case.physics is None:
        return {"seed": seed, "control": True, "effect_to_noise": None}
    f = case.band_hz[1] * np.arange(1, case.n_lines + 1) / case.n_lines
    hits = [(n, abs(d)) for n, d in case.hits]
    sens = [(n, abs(d)) for n, d in case.sensors]
    w2 = (2 * np.pi * f) ** 2
    A1 = w2 * build_truth(case.frame, case.refine, case.errors, case.eta, case.physics).receptance(f, hits, sens)
    A0 = w2 * build_truth(case.frame, case.refine, case.errors, case.eta, None).receptance(f, hits, sens)
    # the generator's noise on H1 at each line: case.noise x the record's RMS over the band (floored at 1e-3 of
    # the channel's largest) divided by the force spectrum there, over n_avg averages; the force is the
    # generator's half-sine pulse (its duration is the first draw of the case's test stream), without the
    # +-15 % amplitude scatter from hit to hit
    tau = np.random.default_rng(10_000 + seed).uniform(0.3, 0.45) / case.band_hz[1]
    shape = np.abs(np.cos(np.pi * f * tau) / (1 - (2 * f * tau) ** 2))
    rms = np.sqrt(np.mean(np.abs(A1 * shape) ** 2, axis=2))
    rms = np.maximum(rms, 1e-3 * rms.max(axis=0, keepdims=True))
    sigma = case.noise * rms[:, :, None] / (shape * np.sqrt(case.n_avg))
    # a pair no force reaches (an out-of-plane hit, in-plane sensors on a planar frame: case 2289) is zero with
    # and without the effect, and noiseless: it says nothing and is left out (it made the mean 0/0)
    seen = sigma > 0
    chi2 = float(np.mean(np.abs(A1 - A0)[seen] ** 2 / sigma[seen] ** 2))
    return {"seed": seed, "control": False, "physics": case.physics["physics"],
            "chi2_per_value": chi2, "effect_to_noise": float(np.sqrt(chi2))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", help="folder of generated cases (generate.py --out)")
    a = ap.parse_args(argv)
    for d in sorted(p for p in Path(a.root).iterdir() if (p / "truth.json").exists()):
        seed = json.loads((d / "truth.json").read_text())["seed"]
        v = effect_to_noise(seed)
        (d / NAME).write_text(json.dumps(v, indent=1))
        e = v["effect_to_noise"]
        print(f"{d.name:<32} {'control' if e is None else f'effect / noise {e:.3g}'}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
