"""Maxwell–Betti reciprocity for roving-hammer data.

In a roving-hammer test a few accelerometers stay fixed while the hammer visits many points, so
the measured FRF matrix has the accelerometers as *responses* and the hit points as
*references*.  For a linear structure with symmetric M, C, K (and D) the receptance matrix is
symmetric, ``H_ij = H_ji`` (Maxwell–Betti; Ewins 2000, ch. 2), and so are the mobility and
accelerance matrices (the same factor iω or −ω² multiplies both).  Transposing the measured set
therefore gives the matrix a shaker test with the accelerometers as references would have
produced: many response DOFs, few references — the layout poly-reference identification wants.
The thesis does exactly this in section 5.3: 12 accelerometers and 36 impact points (66 impact
DOFs) are "re-ordered by using the reciprocity rule in order to have 36 measurement and 12
excitation points" before PolyMAX.

Signs: a DOF label carries the direction in which the sensor measures or the hammer pushes
(``3-Z``: hit in −Z).  The FRF between two signed labels is the same number whichever is the
input, so the transpose keeps each value with its pair of labels; :func:`reorder_by_reciprocity` can
restate the result on positive directions (``positive=True``), negating the data once for each
negative label, which is what :meth:`modalab.core.frf.FRF.select` does with opposite signs.

:func:`reciprocity_check` compares, for every pair of DOFs measured both ways (a response of
one column is the reference of another and vice versa), ``H_ab`` with ``H_ba``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from modalab.core.dof import Dof
from modalab.core.errors import ModalabValueError
from modalab.core.frf import FRF

__all__ = ["reorder_by_reciprocity", "ReciprocityPair", "ReciprocityReport", "reciprocity_check"]

log = logging.getLogger(__name__)


def reorder_by_reciprocity(frf: FRF, *, positive: bool = False, references=None) -> FRF:
    """Roving-hammer FRFs re-ordered by reciprocity: accelerometers become the references.

    Parameters
    ----------
    frf : FRF with ``responses`` = the fixed sensors and ``references`` = the hit DOFs, e.g. the
        result of :func:`acquisition.spectral.estimate_frf_roving`.
    positive : restate every label with a positive direction (``3-Z`` → ``3+Z``), negating the data
        once per negative label, so sets taken with mixed hammer directions line up.
    references : optionally keep only these sensor DOFs as references (labels of ``frf.responses``;
        an opposite sign negates).

    Returns
    -------
    FRF with ``responses`` = the hit DOFs, ``references`` = the sensor DOFs, ``H[j, i] = frf.H[i, j]``,
    coherence carried along (transposed), metadata ``reciprocity = True`` and
    ``measured_references`` (the hit DOFs the data were measured with).
    """
    if not isinstance(frf, FRF):
        raise ModalabValueError(f"reorder_by_reciprocity expects a modalab.core.frf.FRF; got {type(frf).__name__}")
    src = frf if references is None else frf.select(responses=references)
    out = src.transpose()
    if positive:
        out = out.select(responses=[d.positive for d in out.responses],
                         references=[d.positive for d in out.references])
    out.metadata["reciprocity"] = True
    out.metadata["measured_references"] = [str(d) for d in frf.references]
    out.metadata["measured_responses"] = [str(d) for d in src.responses]
    return out


@dataclass(frozen=True)
class ReciprocityPair:
    """One pair of DOFs measured both ways.

    ``rel_diff`` — mean over the compared lines of ``|H_ab − H_ba| / (½(|H_ab| + |H_ba|))`` (0 = equal,
    2 = opposite); ``norm_rel_diff`` — ``‖H_ab − H_ba‖ / (½(‖H_ab‖ + ‖H_ba‖))`` over the band (weighted by
    amplitude, dominated by resonances); ``max_rel_diff`` — the worst line; ``n_lines`` — lines compared.
    """

    dof_a: Dof
    dof_b: Dof
    rel_diff: float
    norm_rel_diff: float
    max_rel_diff: float
    worst_freq_hz: float
    n_lines: int

    def to_dict(self) -> dict:
        return {"dof_a": str(self.dof_a), "dof_b": str(self.dof_b), "rel_diff": self.rel_diff,
                "norm_rel_diff": self.norm_rel_diff, "max_rel_diff": self.max_rel_diff,
                "worst_freq_hz": self.worst_freq_hz, "n_lines": self.n_lines}


@dataclass(frozen=True)
class ReciprocityReport:
    """Pairs measured both ways, sorted worst (largest ``rel_diff``) first."""

    pairs: tuple = ()
    band_hz: tuple = (None, None)
    min_coherence: float | None = None
    details: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.pairs)

    def __iter__(self):
        return iter(self.pairs)

    @property
    def worst(self) -> ReciprocityPair | None:
        return self.pairs[0] if self.pairs else None

    @property
    def max_rel_diff(self) -> float:
        """Largest frequency-averaged relative difference (0 when no pair was measured both ways)."""
        return self.pairs[0].rel_diff if self.pairs else 0.0

    def to_dict(self) -> dict:
        return {"band_hz": list(self.band_hz), "min_coherence": self.min_coherence,
                "pairs": [p.to_dict() for p in self.pairs]}

    def summary(self, n: int = 10) -> str:
        if not self.pairs:
            return "no DOF pair is measured both ways; reciprocity cannot be checked"
        lines = [f"{len(self.pairs)} pair(s) measured both ways (worst first):"]
        for p in self.pairs[:n]:
            lines.append(f"  {p.dof_a} <-> {p.dof_b}: mean {100 * p.rel_diff:.2f} %, norm "
                         f"{100 * p.norm_rel_diff:.2f} %, worst {100 * p.max_rel_diff:.1f} % at {p.worst_freq_hz:.4g} Hz")
        return "\n".join(lines)


def reciprocity_check(frf: FRF, *, band_hz: tuple | None = None, min_coherence: float | None = None) -> ReciprocityReport:
    """Compare ``H_ab`` with ``H_ba`` for every pair of distinct DOFs measured both ways.

    Parameters
    ----------
    frf : any FRF; a pair (a, b) is checked when a is a response and b a reference and b is also a
        response and a also a reference (matching node and axis; signs of the labels are honoured).
    band_hz : ``(lo, hi)`` to compare only lines in that band (Hz).
    min_coherence : compare only lines where both FRFs have coherence ≥ this (needs ``frf.coherence``).

    Returns
    -------
    ReciprocityReport with one :class:`ReciprocityPair` per unordered pair, worst first.
    """
    if not isinstance(frf, FRF):
        raise ModalabValueError(f"reciprocity_check expects a modalab.core.frf.FRF; got {type(frf).__name__}")
    lines = np.ones(frf.n_freq, bool)
    if band_hz is not None:
        lo, hi = band_hz
        lines &= (frf.freq_hz >= (-np.inf if lo is None else lo)) & (frf.freq_hz <= (np.inf if hi is None else hi))
        if not lines.any():
            raise ModalabValueError(f"band_hz={band_hz} holds no line of the FRF ({frf.freq_hz[0]:.4g}.."
                                    f"{frf.freq_hz[-1]:.4g} Hz)")
    if min_coherence is not None and frf.coherence is None:
        raise ModalabValueError("min_coherence given but the FRF carries no coherence; drop min_coherence")
    resp = {(d.node, d.axis): (i, d.sign) for i, d in enumerate(frf.responses)}
    refs = {(d.node, d.axis): (j, d.sign) for j, d in enumerate(frf.references)}
    both = [k for k in resp if k in refs]
    pairs = []
    for ia, a in enumerate(both):
        for b in both[ia + 1:]:
            i_a, s_ra = resp[a]
            j_b, s_fb = refs[b]
            i_b, s_rb = resp[b]
            j_a, s_fa = refs[a]
            # both expressed on positive labels
            Hab = frf.H[i_a, j_b] * (s_ra * s_fb)
            Hba = frf.H[i_b, j_a] * (s_rb * s_fa)
            m = lines.copy()
            if min_coherence is not None:
                m &= (frf.coherence[i_a, j_b] >= min_coherence) & (frf.coherence[i_b, j_a] >= min_coherence)
            m &= np.isfinite(Hab) & np.isfinite(Hba)
            A, B = Hab[m], Hba[m]
            scale = 0.5 * (np.abs(A) + np.abs(B))
            ok = scale > 0
            if not ok.any():
                log.info("pair %s/%s has no comparable line", a, b)
                continue
            rel = np.abs(A - B)[ok] / scale[ok]
            k = int(np.argmax(rel))
            norm = float(np.linalg.norm(A - B) / (0.5 * (np.linalg.norm(A) + np.linalg.norm(B))))
            pairs.append(ReciprocityPair(dof_a=Dof(a[0], a[1]), dof_b=Dof(b[0], b[1]), rel_diff=float(rel.mean()),
                                         norm_rel_diff=norm, max_rel_diff=float(rel[k]),
                                         worst_freq_hz=float(frf.freq_hz[m][ok][k]), n_lines=int(ok.sum())))
    pairs.sort(key=lambda p: p.rel_diff, reverse=True)
    return ReciprocityReport(pairs=tuple(pairs), band_hz=tuple(band_hz) if band_hz is not None else (None, None),
                             min_coherence=min_coherence)
