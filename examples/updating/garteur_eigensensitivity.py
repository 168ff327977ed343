"""Thesis section 5.3: inverse eigensensitivity updating of a GARTEUR SM-AG19-like model (Tables 10, 11).

Usage::

    python examples/updating/garteur_eigensensitivity.py OUT_DIR

The case (``updating.fe.models.garteur_cases``): a nominal beam model whose wing-torsion pair lies below
the wing-bending/tail-plane mode, a pseudo-experimental truth (stiffer wing torsion, thinner fin,
stiffer fin spring, plus small errors that are not updated) measured at 28 accelerometer DOFs.  The
nominal is written as a Nastran deck, read back and updated there (wing-tip torsion springs, fin
torsion spring, fin thickness; frequency residuals, MAC re-pairing at every iteration); the updated
deck is exported and re-imported to check its frequencies.  Prints the Table 10- and Table 11-like
tables, the sensitivity ranking, identifiability and parameter history; saves to OUT_DIR the MAC
matrices before/after, the frequency comparison, the parameter convergence and the two decks.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import numpy as np  # noqa: E402

from updating.fe.bulk import build_model, read_bdf, to_bulk, write_bdf  # noqa: E402
from updating.correlation.metrics import mac, pair_modes  # noqa: E402
from updating.correlation.plots import plot_frequencies, plot_mac  # noqa: E402
from updating.methods.eigensensitivity import InverseEigensensitivity, identifiability, sensitivity_ranking  # noqa: E402
from updating.methods.mci import plot_convergence  # noqa: E402
from updating.fe.models.garteur_cases import (TRUE_VALUES, UPDATING_PARAMETERS, modal_test, nominal_model,  # noqa: E402
                                           truth_model, updating_model)

TABLE11_ERR_PCT = [0.18, 7.3, 0.95, 0.08, 0.05, 1.28, 0.97, 0.44, 0.21, 0.01]


def elastic_at(model, dofs, n=10):
    return model.modes(6 + n).select_modes(np.arange(6, 6 + n)).select_dofs(dofs)


def correlation_table(title, a, test, tol_col=False):
    M = mac(a.shapes, test.shapes)
    pairs = {int(x): int(i) for i, x in pair_modes(M, mac_min=0.5).pairs}
    print(title)
    head = f"{'test mode':>9} {'f test (Hz)':>11} {'FE mode':>8} {'f FE (Hz)':>10} {'MAC':>6} {'error %':>8}"
    print(head + (f" {'Table 11 %':>10}" if tol_col else ""))
    for x in range(test.n_modes):
        i = pairs.get(x)
        if i is None:
            print(f"{x + 1:9d} {test.freq_hz[x]:11.2f} {'-':>8}")
            continue
        e = 100 * (a.freq_hz[i] - test.freq_hz[x]) / test.freq_hz[x]
        line = f"{x + 1:9d} {test.freq_hz[x]:11.2f} {i + 1:8d} {a.freq_hz[i]:10.2f} {M[i, x]:6.3f} {e:8.3f}"
        print(line + (f" {TABLE11_ERR_PCT[x]:10.2f}" if tol_col else ""))
    print()
    return M, [(i, x) for x, i in sorted(pairs.items())]


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print(__doc__)
        return 2
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    nominal = nominal_model()
    test = modal_test(truth_model())
    print(f"test: {test.n_modes} modes at {len(test.dofs)} DOFs: {' '.join(str(d) for d in test.dofs)}\n")

    deck = out / "garteur_nominal.bdf"
    write_bdf(to_bulk(nominal), deck)
    model = build_model(read_bdf(deck))
    pm = updating_model(model)
    a0 = elastic_at(model, test.dofs)
    M0, pairs0 = correlation_table("Initial correlation (cf. thesis Table 10)", a0, test)
    plot_mac(M0, out / "mac_initial.png", analysis_freq_hz=a0.freq_hz, test_freq_hz=test.freq_hz, pairs=pairs0,
             title="MAC: nominal vs test")

    print("Sensitivity ranking (frequency residuals):")
    for name, nrm in sensitivity_ranking(pm, test, use_shapes=False):
        print(f"  {name:>16} {nrm:10.3g}")
    idf = identifiability(pm, test, use_shapes=False)
    print(f"singular values {np.array2string(idf['singular_values'], precision=3)}, rank {idf['rank']}, "
          f"condition {idf['condition']:.3g}\n")

    u = InverseEigensensitivity(use_shapes=False, bounds=([0.0, 0.0, 0.5], [1e5, 1e5, 2.0])).fit(pm, test)
    print(f"converged {u.converged_} in {u.n_iter_} iterations")
    H = np.vstack([pm.p0] + [h["p"] for h in u.history_])
    print(f"{'iteration':>9} " + " ".join(f"{n:>16}" for n in pm.parameter_names))
    for k, row in enumerate(H):
        print(f"{k:9d} " + " ".join(f"{v:16.5g}" for v in row))
    print(f"{'truth':>9} " + " ".join(f"{TRUE_VALUES[n]:16.5g}" for n in UPDATING_PARAMETERS))
    print(f"{'std':>9} " + " ".join(f"{v:16.3g}" for v in u.std_) + "\n")
    plot_convergence(H, out / "convergence.png", names=pm.parameter_names)

    updated = pm.model_at(u.p_)
    updated_deck = out / "garteur_updated.bdf"
    write_bdf(to_bulk(updated, template=read_bdf(deck)), updated_deck)
    again = build_model(read_bdf(updated_deck))
    a1 = elastic_at(again, test.dofs)
    M1, pairs1 = correlation_table("Updated correlation, re-imported updated deck (cf. thesis Table 11)", a1, test,
                                   tol_col=True)
    plot_mac(M1, out / "mac_updated.png", analysis_freq_hz=a1.freq_hz, test_freq_hz=test.freq_hz, pairs=pairs1,
             title="MAC: updated vs test")
    for tag, a, pairs in (("initial", a0, pairs0), ("updated", a1, pairs1)):
        plot_frequencies(test.freq_hz[[x for _, x in pairs]], a.freq_hz[[i for i, _ in pairs]],
                         out / f"frequencies_{tag}.png", labels=[f"{x + 1}/{i + 1}" for i, x in pairs],
                         title=f"Natural frequencies: {tag} vs test")
    dev = np.max(np.abs(a1.freq_hz - u.freq_a_hz_) / u.freq_a_hz_)
    print(f"re-imported updated deck vs updater: max relative frequency difference {dev:.2e}")
    print(f"decks and figures written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
