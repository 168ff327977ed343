"""Test–analysis correlation — thesis section 2.2.

Mode-shape criteria (shapes are ``(n_dof, n_modes)`` arrays or
:class:`~modalab.core.modes.ModeSet` objects on the same DOFs):

* :func:`mac` — Modal Assurance Criterion, eq. 2.63 (complex-aware, optional weighting);
  :func:`automac` — MAC of a set with itself; :func:`macx` — the complex MAC (MACX).
* :func:`msf` — Modal Scale Factor, eq. 2.62.
* :func:`comac` — Coordinate MAC, eq. 2.64; :func:`ecomac` — enhanced COMAC.
* :func:`cross_orthogonality`, :func:`mixed_orthogonality` — eqs. 2.65, 2.66.
* :func:`frequency_table` — direct comparison of paired frequencies (section 2.2.1).

Pairing: :func:`pair_modes` — the one pairing rule of modalab (``correlate``, every
updating method and the diagnosis fit call it): Hungarian assignment on
``(1 − MAC) + relative frequency distance`` inside a frequency window (default
±35 %) with a MAC floor (0.5), the option of leaving a mode unpaired, analysis
modes the sensors cannot observe and rigid-body modes kept out and said so, a
reason for every unpaired test mode, and pairing by frequency order for
frequency-only sets.  It reports pairs whose order differs between the models
(the thesis' scaled aircraft, Table 10, had test modes 3–5 paired with FE modes
5, 3, 4 and 9–10 with 10, 9 — the latter at +22.7 %, inside the window).
Deterministic: no random start, no set or dict order.

FRF criteria: :func:`frac` (FRF assurance criterion per FRF over frequency),
:func:`csac` and :func:`csf` (cross-signature assurance and scale factor per
frequency line), :func:`frf_correlation` for labelled FRFs or a Structure.

High level: :func:`correlate` maps the analysis modes onto the test DOFs,
computes the MAC matrix, pairs the modes and returns a :class:`CorrelationResult`
with frequency errors, MSF, COMAC and ECOMAC, ``to_dict()`` for JSON and
``table()`` for text; the analysis may be a Structure (:func:`analysis_modes`
computes its normal modes).  Mode numbers in ``to_dict()`` and ``table()`` are 1-based;
indices in Python attributes are 0-based.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError
from modalab.core.frf import roving_hammer_layout
from modalab.core.modes import ModeSet
from modalab.core.structure import Structure

from updating.correlation.dofmap import as_dofmap
# the criteria and the pairing rule live in three modules, re-exported here (this stays the import path of
# every public name: __all__ below and updating.correlation)
from updating.correlation.frf_criteria import FrfCorrelation, csac, csf, frac, frf_correlation  # noqa: F401
from updating.correlation.pairing import (CLOSE_MODES, FREQ_WEIGHT, FREQ_WINDOW, MAC_MIN, MERGE_GAIN,  # noqa: F401
                                          MIN_OBSERVABILITY, Pairing, observability, pair_modes, shape_noise,
                                          span_mac)
from updating.correlation.shape_criteria import (automac, comac, cross_orthogonality, ecomac, mac, macx,  # noqa: F401
                                                 mixed_orthogonality, msf)

__all__ = ["mac", "automac", "macx", "msf", "comac", "ecomac", "cross_orthogonality", "mixed_orthogonality",
           "frequency_table", "Pairing", "pair_modes", "span_mac", "shape_noise", "CLOSE_MODES", "MERGE_GAIN",
           "observability", "MAC_MIN", "FREQ_WINDOW",
           "FREQ_WEIGHT", "MIN_OBSERVABILITY", "frac", "csac", "csf", "FrfCorrelation",
           "frf_correlation", "CorrelationResult", "correlate", "analysis_modes"]


def frequency_table(freq_a_hz, freq_x_hz, pairs) -> list[dict]:
    """Paired frequencies and relative errors ``(f_a - f_x)/f_x`` in %, one dict per pair (0-based indices)."""
    fa, fx = np.asarray(freq_a_hz, float), np.asarray(freq_x_hz, float)
    rows = []
    for ia, jx in pairs:
        err = (fa[ia] - fx[jx]) / fx[jx] * 100 if fx[jx] != 0 else (0.0 if fa[ia] == 0 else np.inf)
        rows.append({"analysis": int(ia), "test": int(jx), "analysis_freq_hz": float(fa[ia]),
                     "test_freq_hz": float(fx[jx]), "freq_error_pct": float(err)})
    return rows


# -------------------------------------------------------------------- high level
def _enc(v):
    v = complex(v)
    return v.real if v.imag == 0 else {"re": v.real, "im": v.imag}


@dataclass
class CorrelationResult:
    """Everything :func:`correlate` found (0-based indices in attributes).

    analysis : analysis modes observed at the test DOFs.
    test : test modes.
    mac : (n_analysis, n_test) MAC matrix (NaN everywhere for a frequency-only test set).
    pairing : :class:`Pairing`.
    freq_error_pct : (n_pairs,) ``(f_a - f_x)/f_x`` in %.
    msf : (n_pairs,) factor scaling each analysis mode onto its test mode (eq. 2.62).
    comac, ecomac : (n_test_dofs,) per test DOF over the pairs.
    mac_min : threshold used.
    observability : (n_analysis,) observed/full amplitude of each analysis mode (:func:`observability`).
    dof_mapping : how test DOFs were put on model DOFs (a sentence), and ``geometry`` the
        per-node distances when they were mapped by geometry.
    """

    analysis: ModeSet
    test: ModeSet
    mac: np.ndarray
    pairing: Pairing
    freq_error_pct: np.ndarray
    msf: np.ndarray
    comac: np.ndarray
    ecomac: np.ndarray
    mac_min: float
    observability: np.ndarray = None
    dof_mapping: str = "same node ids"
    geometry: dict = None

    @property
    def pairs(self) -> list:
        return self.pairing.pairs

    @property
    def dofs(self) -> list:
        return self.test.dofs

    @property
    def has_shapes(self) -> bool:
        return self.test.has_shapes

    def paired(self) -> tuple[ModeSet, ModeSet]:
        """(analysis, test) mode sets restricted to the pairs, in pair order."""
        return (self.analysis.select_modes(self.pairing.analysis_index),
                self.test.select_modes(self.pairing.test_index))

    def summary(self) -> dict:
        fe = np.abs(self.freq_error_pct)
        shp = self.has_shapes and len(self.pairs)
        return {"n_pairs": len(self.pairs), "n_test_modes": self.test.n_modes,
                "n_analysis_modes": self.analysis.n_modes,
                "n_unpaired_test_modes": len(self.pairing.unpaired_test),
                "mean_abs_freq_error_pct": float(fe.mean()) if fe.size else None,
                "max_abs_freq_error_pct": float(fe.max()) if fe.size else None,
                "min_pair_mac": float(self.pairing.mac.min()) if shp else None,
                "mean_pair_mac": float(self.pairing.mac.mean()) if shp else None,
                "n_test_dofs": len(self.test.dofs) if self.has_shapes else 0,
                "mac_warning": self.mac_warning()}

    def mac_warning(self) -> str | None:
        """A warning when the MAC rests on fewer measured DOFs than paired modes, else None.

        With ``n`` DOFs at most ``n`` shapes are independent: more paired modes than DOFs cannot all be told
        apart by their shapes (on one DOF every MAC is 1), so the MAC does not confirm those pairs."""
        n_dof, n_pairs = len(self.test.dofs), len(self.pairs)
        if not self.has_shapes or n_dof >= n_pairs:
            return None
        s = "s" if n_dof != 1 else ""
        head = (f"the MAC rests on {n_dof} measured DOF{s} for {n_pairs} paired modes: so few DOFs cannot tell the "
                "shapes apart (on one DOF every MAC is 1), the pairs stand on frequency alone; ")
        refs = list(self.test.references or [])
        if roving_hammer_layout(len(refs), n_dof):
            # shapes at the accelerometers, participation at the hit points: identified from a roving-hammer file
            # without the reciprocity transposition (identify --no-reciprocity)
            return head + (f"these modes have their shapes at the {n_dof} response DOF{s} "
                           f"({', '.join(str(d) for d in self.test.dofs[:3])}{' ...' if n_dof > 3 else ''}) and "
                           f"their participation at {len(refs)} references, the hit points of a roving-hammer test: "
                           "identify the FRF file again without --no-reciprocity (identify transposes it by "
                           f"reciprocity, so the {len(refs)} hit points become the shapes' DOFs) and correlate "
                           "those modes")
        return head + ("measure more response DOFs; if the modes come from a roving-hammer file (the hit points as its "
                       "references, more of them than responses) identified with --no-reciprocity, identify it "
                       "without --no-reciprocity: identify then transposes it so that the hit points become the DOFs")

    def to_dict(self) -> dict:
        """JSON-ready dict; mode numbers are 1-based."""
        fa, fx = self.analysis.freq_hz, self.test.freq_hz
        ooo = set(self.pairing.out_of_order)
        pairs = []
        for k, (ia, jx) in enumerate(self.pairs):
            pairs.append({"test_mode": jx + 1, "analysis_mode": ia + 1, "test_freq_hz": float(fx[jx]),
                          "analysis_freq_hz": float(fa[ia]), "freq_error_pct": float(self.freq_error_pct[k]),
                          "mac": float(self.pairing.mac[k]) if self.has_shapes else None,
                          "msf": _enc(self.msf[k]) if self.has_shapes else None,
                          "out_of_order": (ia, jx) in ooo})
        out = {
            "test_dofs": [str(d) for d in self.test.dofs],
            "test_freq_hz": fx.tolist(), "analysis_freq_hz": fa.tolist(),
            "mac_min": self.mac_min, "mac": self.mac.tolist() if self.has_shapes else None, "pairs": pairs,
            "pairing": self.pairing.to_dict(), "dof_mapping": self.dof_mapping,
            "unpaired_test_modes": [j + 1 for j in self.pairing.unpaired_test],
            "unpaired_analysis_modes": [i + 1 for i in self.pairing.unpaired_analysis],
            "comac": {str(d): float(v) for d, v in zip(self.test.dofs, self.comac)},
            "ecomac": {str(d): float(v) for d, v in zip(self.test.dofs, self.ecomac)},
            "summary": self.summary(),
        }
        if self.observability is not None:
            out["analysis_observability"] = [float(v) for v in self.observability]
        if self.geometry is not None:
            out["geometry_map"] = self.geometry
        return out

    def table(self, *, mac_warning: bool = True) -> str:
        """Plain-text frequency and MAC comparison (1-based mode numbers), with how the pairs were made, and the
        warning when the MAC rests on too few DOFs (``mac_warning=False``: without it, e.g. below a table that
        gave it already)."""
        fa, fx = self.analysis.freq_hz, self.test.freq_hz
        ooo = set(self.pairing.out_of_order)
        lines = [f"DOFs: {self.dof_mapping}", f"pairing: {self.pairing.method}"]
        if not self.has_shapes:
            lines.append("the test set has no mode shapes: no MAC, pairs by frequency order only")
        lines.append(f"{'test':>4} {'f_test [Hz]':>12} {'FE':>4} {'f_FE [Hz]':>12} {'df [%]':>8} {'MAC':>6} "
                     f"{'|MSF|':>9}  note")
        by_test = {jx: (k, ia) for k, (ia, jx) in enumerate(self.pairs)}
        rigid = {jx: ia for ia, jx in self.pairing.rigid_pairs}
        for jx in range(self.test.n_modes):
            if jx in by_test:
                k, ia = by_test[jx]
                note = "out of order" if (ia, jx) in ooo else ""
                m = f"{self.pairing.mac[k]:>6.3f}" if self.has_shapes else f"{'-':>6}"
                s = f"{abs(self.msf[k]):>9.4g}" if self.has_shapes else f"{'-':>9}"
                lines.append(f"{jx + 1:>4} {fx[jx]:>12.4f} {ia + 1:>4} {fa[ia]:>12.4f} "
                             f"{self.freq_error_pct[k]:>+8.2f} {m} {s}  {note}")
            elif jx in rigid:
                ia = rigid[jx]
                lines.append(f"{jx + 1:>4} {fx[jx]:>12.4f} {ia + 1:>4} {fa[ia]:>12.4f} {'-':>8} "
                             f"{self.mac[ia, jx]:>6.3f} {'-':>9}  rigid-body pair (not in any objective)")
            else:
                lines.append(f"{jx + 1:>4} {fx[jx]:>12.4f} {'-':>4} {'-':>12} {'-':>8} {'-':>6} {'-':>9}  "
                             f"unpaired: {self.pairing.unpaired_reason.get(jx, '')}")
        if len(fx):
            excl = self.pairing.excluded_analysis
            # the test band: from the lowest to the highest test mode, 10 % either side (the file does not say
            # which band was identified; a model mode below the lowest test mode is not "in the band")
            lo, hi = fx.min() / 1.1, fx.max() * 1.1
            band = [i for i in self.pairing.unpaired_analysis if lo <= fa[i] <= hi and i not in excl]
            if band:
                lines.append("analysis modes in the test band without a test partner: "
                             + ", ".join(f"{i + 1} ({fa[i]:.4g} Hz)" for i in band))
            ex = [i for i in sorted(excl) if fa[i] <= hi]
            if ex:
                lines.append("analysis modes kept out of the pairing: "
                             + "; ".join(f"{i + 1} ({fa[i]:.4g} Hz) {excl[i]}" for i in ex))
        s = self.summary()
        if s["n_pairs"]:
            lines.append(f"{s['n_pairs']} pairs, {s['n_unpaired_test_modes']} test mode(s) unpaired; mean |df| "
                         f"{s['mean_abs_freq_error_pct']:.2f} %"
                         + (f", min MAC {s['min_pair_mac']:.3f}" if s["min_pair_mac"] is not None else ""))
        else:
            lines.append("no pairs: " + self.pairing.method)
        if s["mac_warning"] and mac_warning:
            lines.append("WARNING: " + s["mac_warning"])
        return "\n".join(lines)


def analysis_modes(structure: Structure, n_modes: int | None = None) -> ModeSet:
    """Mass-normalised normal modes of a Structure as a :class:`~modalab.core.modes.ModeSet` (Hz, undamped)."""
    if not isinstance(structure, Structure):
        raise ModalabValueError(f"expected a Structure; got {type(structure).__name__}")
    if n_modes is not None and not 1 <= int(n_modes) <= structure.n_dof:
        raise ModalabValueError(f"n_modes {n_modes}; expected 1..{structure.n_dof} (the model's DOF count)")
    omega, phi = structure.normal_modes(None if n_modes is None else int(n_modes))
    return ModeSet(freq_hz=omega / (2 * np.pi), shapes=phi, dofs=structure.dofs, scaling="unit_modal_mass",
                   metadata={"source": f"normal modes of {structure.name or 'the model'}"})


def correlate(analysis, test: ModeSet, *, dofmap=None, mac_min: float = MAC_MIN, freq_weight: float | None = None,
              max_freq_error: float | None = FREQ_WINDOW, n_analysis_modes: int | None = None,
              min_observability: float = MIN_OBSERVABILITY, rigid_hz: float | None = None,
              rigid: str = "exclude", dof_mapping: str | None = None, geometry: dict | None = None,
              log_unpaired: bool = True) -> CorrelationResult:
    """Correlate analysis modes with test modes on the test DOFs.

    The analysis modes are observed at the test DOFs through ``dofmap``
    (:class:`~updating.correlation.dofmap.DofMap`, dict, TOML/CSV path, or None for the same
    node numbers — the CLI refuses that without ``--same-ids`` and maps by geometry
    instead, :func:`updating.correlation.dofmap.geometry_map`; unmapped test DOFs raise
    :class:`~modalab.core.errors.DofError`).  Then: MAC matrix (eq. 2.63), the one
    pairing rule :func:`pair_modes` (Hungarian assignment on MAC and frequency, a
    frequency window, unobservable and rigid-body analysis modes kept out and said
    so), frequency errors (section 2.2.1), MSF (eq. 2.62), COMAC (eq. 2.64) and
    ECOMAC over the pairs.  Complex test shapes are used as they are (the MAC is
    complex-aware).  A frequency-only test set (no shapes) is paired by frequency order
    inside the window.

    ``analysis`` may also be a :class:`~modalab.core.structure.Structure`: its lowest
    ``n_analysis_modes`` normal modes are used (default: twice the number of test
    modes plus 5, at most the model size).  ``dof_mapping``/``geometry`` only label the
    result (how the map was made, distances of a geometry map).  ``log_unpaired``: as in :func:`pair_modes`.
    """
    if isinstance(analysis, Structure):
        if not isinstance(test, ModeSet):
            raise ModalabValueError(f"test: got {type(test).__name__}; expected a modalab.core.modes.ModeSet")
        n = n_analysis_modes or min(analysis.n_dof, 2 * test.n_modes + 5)
        analysis = analysis_modes(analysis, n)
    for name, ms in (("analysis", analysis), ("test", test)):
        if not isinstance(ms, ModeSet):
            raise ModalabValueError(f"{name}: got {type(ms).__name__}; expected a modalab.core.modes.ModeSet")
    if dof_mapping is None:
        dof_mapping = ("same node ids (no map given)" if dofmap is None else
                       f"DOF map {getattr(as_dofmap(dofmap), 'name', '') or 'given'}")
    if not test.has_shapes:
        fa = analysis.freq_hz
        pairing = pair_modes(None, fa, test.freq_hz, mac_min=mac_min, max_freq_error=max_freq_error,
                             rigid_hz=rigid_hz, rigid="exclude", log_unpaired=log_unpaired)
        rows = frequency_table(fa, test.freq_hz, pairing.pairs)
        ana = analysis.select_dofs([]) if analysis.n_dof else analysis
        return CorrelationResult(analysis=ana, test=test, mac=np.full((analysis.n_modes, test.n_modes), np.nan),
                                 pairing=pairing, freq_error_pct=np.array([r["freq_error_pct"] for r in rows], float),
                                 msf=np.full(len(pairing.pairs), np.nan), comac=np.zeros(0), ecomac=np.zeros(0),
                                 mac_min=float(mac_min), observability=None, dof_mapping="none (no test shapes)",
                                 geometry=None)
    ana = as_dofmap(dofmap).apply(analysis, test.dofs)
    X = np.asarray(test.shapes)
    A = np.asarray(ana.shapes)
    M = mac(A, X)
    obs = observability(A, analysis.shapes, analysis.dofs)
    pairing = pair_modes(M, ana.freq_hz, test.freq_hz, mac_min=mac_min, freq_weight=freq_weight,
                         max_freq_error=max_freq_error, observability=obs, min_observability=min_observability,
                         rigid_hz=rigid_hz, rigid=rigid, mode_shapes=(A, X), log_unpaired=log_unpaired)
    ia, jx = pairing.analysis_index, pairing.test_index
    rows = frequency_table(ana.freq_hz, test.freq_hz, pairing.pairs)
    ferr = np.array([r["freq_error_pct"] for r in rows], float)
    if len(ia):
        Ap, Xp = A[:, ia], X[:, jx]
        s = msf(Xp, Ap)
        cm, ec = comac(Ap, Xp), ecomac(Ap, Xp)
    else:
        s, cm, ec = np.zeros(0), np.zeros(test.n_dof), np.zeros(test.n_dof)
    return CorrelationResult(analysis=ana, test=test, mac=M, pairing=pairing, freq_error_pct=ferr, msf=np.asarray(s),
                             comac=cm, ecomac=ec, mac_min=float(mac_min), observability=obs,
                             dof_mapping=dof_mapping, geometry=geometry)
