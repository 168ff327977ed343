"""What a diagnosis concludes: :class:`Finding` (one named piece of missing physics, with its alternatives when
ambiguous), :class:`Diagnosis` (findings, parameters, fit blocks, decisions; ``diagnosis.json``) and the
plain-language :func:`statement`.  Split out of :mod:`~updating.diagnosis.workflow`."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from updating.fe import FEModel
from updating.diagnosis.library import SPRING_LOSS, Candidate

log = logging.getLogger(__name__)


@dataclass
class Finding:
    candidate: Candidate
    value: float
    std: float
    evidence: str
    gain_train: float = 0.0
    parts: list = field(default_factory=list)          # [(Candidate, value, std)] refining this finding nearby
    alternatives: list = field(default_factory=list)   # [(Candidate, value, ...)] explaining the data equally well

    @property
    def ambiguous(self) -> bool:
        return bool(self.alternatives)

    @property
    def label(self) -> str:
        c = self.candidate
        s = c.label + "".join(_part(c, o, v) for o, v, _ in self.parts)
        if self.alternatives:
            s += or_labels(c, [o for o, *_ in self.alternatives])
        return s

    def to_dict(self) -> dict:
        c = self.candidate
        return {"physics": c.physics, "nodes": [int(n) for n in c.nodes], "dofs": list(c.dofs),
                "elements": [int(e) for e in c.elements], "description": self.label,
                "values": [{"name": c.value_name, "value": float(self.value), "unit": c.unit,
                            "std": float(self.std) if np.isfinite(self.std) else None}],    # inf: not determined
                "parts": [{"physics": o.physics, "nodes": [int(n) for n in o.nodes], "dofs": list(o.dofs),
                           "description": o.label, "value": float(v), "unit": o.unit,
                           "std": float(sd) if np.isfinite(sd) else None}
                          for o, v, sd in self.parts],
                "ambiguous": self.ambiguous,
                "alternatives": [{"physics": o.physics, "nodes": [int(n) for n in o.nodes], "dofs": list(o.dofs),
                                  "elements": [int(e) for e in o.elements], "description": o.label,
                                  "value": float(v), "unit": o.unit} for o, v, *_ in self.alternatives],
                "evidence": self.evidence}


@dataclass
class Diagnosis:
    findings: list
    parameters: dict
    fit: dict
    statement: str
    model: FEModel                      # the augmented, updated model
    parametric: object = None
    p: np.ndarray = None
    steps: dict = field(default_factory=dict)
    maps: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    ranking: list = field(default_factory=list)
    curves: dict = field(default_factory=dict)
    frequencies: dict = field(default_factory=dict)
    pairing: dict = field(default_factory=dict)     # per fit block: pairs and the modes left out on purpose
    not_evaluated: list = field(default_factory=list)   # candidates whose augmented model could not be solved
    unobservable: list = field(default_factory=list)    # releases the sensors and hits cannot see (not screened)
    decisions: list = field(default_factory=list)       # the selection's verdicts in order: found/ambiguous/
    #                                                     rejected/dropped, each with the candidate and the reason

    def to_dict(self) -> dict:
        return {"findings": [f.to_dict() for f in self.findings], "parameters": self.parameters,
                "fit": self.fit, "statement": self.statement,
                "ranking": [{"candidate": c.label, "physics": c.physics, "explained": round(g, 4)}
                            for c, _, g in self.ranking[:12]],
                "pairing": self.pairing,
                "not_evaluated": list(self.not_evaluated),
                "unobservable": list(self.unobservable),
                "decisions": list(self.decisions),
                "timings_s": {k: round(v, 3) for k, v in self.timings.items()}}


_PHRASES = {
    "ground_spring": ("The test article is held by something the model leaves out", "consistent with an elastic "
                      "suspension or support"),
    "added_mass": ("The test article carries mass the model leaves out", "consistent with sensors, cables or fixtures"),
    "local_damping": ("The test article dissipates energy locally where the model does not",
                      "consistent with a joint, a damping treatment or rubbing contact"),
    "joint_flexibility": ("A joint of the test article is more flexible than the model's rigid connection",
                          "consistent with a bolted or welded connection that is not fully rigid"),
    "boundary_flexibility": ("A support of the test article is not as rigid as the model's constraint",
                             "consistent with a flexible clamp or fixture"),
}


def _fmt(v: float, unit: str) -> str:
    return f"{v:.3g} {unit}".replace(" -", "")


def pct(x: float) -> str:
    """A percentage as the statements print it: two significant digits, no exponent and no digits beyond the
    units above 10 (``0.96``, ``0.004``, ``3.0``, ``4.1``, ``38``, ``0``); a nonzero value never reads ``0``."""
    x = float(x)
    if not np.isfinite(x):
        return str(x)
    if abs(x) >= 9.95:
        return f"{x:.0f}"
    if x == 0:
        return "0"
    return np.format_float_positional(x, precision=2, unique=False, fractional=False, trim="0")   # 3.0, 0.3


def from_to(a: float, b: float) -> str:
    """``from 0.96 % to 0.95 %``, or ``unchanged at 0.96 %`` when the two print alike."""
    sa, sb = pct(a), pct(b)
    return f"unchanged at {sa} %" if sa == sb else f"from {sa} % to {sb} %"


def _part(host: Candidate, part: Candidate, value: float) -> str:
    """`` with <value> at <DOFs>`` for a part of the host's own kind (the rest of a mass lumped on a
    neighbour); a part of another kind is named (a spring's own dashpot: `` with dashpot to ground at 3+Z of
    20 N·s/m``); a spring's own loss factor (:func:`~updating.diagnosis.library.spring_loss_candidates`, its
    CELAS GE on top of PARAM G) is `` with its own loss factor (GE) 0.0135``."""
    where = ", ".join(part.dofs) or ", ".join(map(str, part.nodes))
    if part.label.startswith(SPRING_LOSS):
        return f" with its own loss factor (GE) {_fmt(value, part.unit)}"
    if part.physics == host.physics:
        return f" with {_fmt(value, part.unit)} at {where}"
    return f" with {part.label} of {_fmt(value, part.unit)}"


def _describe(f: Finding) -> str:
    s = f"{f.candidate.label} of {_fmt(f.value, f.candidate.unit)}"
    s += "".join(f" ({_part(f.candidate, o, v)[1:]})" for o, v, _ in f.parts)
    if f.alternatives:
        c = f.candidate
        s = "either " + s + "".join(f" or {_short(c, o)} of {_fmt(v, o.unit)}" for o, v, *_ in f.alternatives) + \
            " (the data cannot tell them apart)"
    return s


def _short(c: Candidate, o: Candidate) -> str:
    """``o``'s label, without the words it shares with ``c``'s before the place (`` at ``): ``at 8+X`` for
    a spring to ground at 8+X beside one at 6+X."""
    what, at, where = o.label.partition(" at ")
    return f"at {where}" if at and c.label.partition(" at ")[0] == what else o.label


def or_labels(c: Candidate, others) -> str:
    """`` or <label>`` for each of ``others`` (alternatives to ``c``), the words shared with ``c`` left out
    (:func:`_short`)."""
    return "".join(f" or {_short(c, o)}" for o in others)


def statement(findings, fit, held_desc: str, not_evaluated=(), unobservable=(), mesh: str | None = None,
              blind: str | None = None, noise_limit: float | None = None) -> str:
    """The diagnosis in words; candidates that could not be evaluated and releases the sensors and hits
    cannot see are named (the conclusion does not cover them); ``mesh``: why the nominal beam mesh's own error
    was taken out of the data (:func:`~updating.diagnosis.mesh.mesh_discrepancy`), said first.
    ``noise_limit``: the χ²/N up to which FRFs are at their noise; without a finding, a parameters-only fit that
    leaves the held-out FRFs above it is said to leave something out (no evidence that nothing is missing)."""
    chi = (fit.get("parameters_only") or {}).get("chi2_per_value_held_out")
    text = _statement(findings, fit, held_desc,
                      above=chi if noise_limit is not None and chi is not None and chi > noise_limit else None)
    if blind and findings:
        text += " " + blind
    if mesh:
        text = (f"The nominal beam mesh's own discretisation error was taken out of the measured FRFs first ({mesh}); "
                "the FRF errors here are against the data so corrected. " + text)
    if unobservable:
        where: dict = {}
        for d in unobservable:
            for dof in d["dofs"] or [str(n) for n in d["nodes"]]:
                node, _, axis = dof.partition("+")
                where.setdefault((d["physics"], axis), []).append(node)
        parts = [f"{kind.replace('_', ' ')}{' about ' + axis if axis else ''} at node{'s' if len(ns) > 1 else ''} "
                 f"{', '.join(dict.fromkeys(ns))}" for (kind, axis), ns in where.items()]
        text += (f" Not observable with these sensors and hits: {'; '.join(parts)} (released completely, it would "
                 "change the measured FRFs by less than their noise); this conclusion does not cover it.")
    if not_evaluated:
        names = ", ".join(d["candidate"] for d in not_evaluated[:3]) + (" and others" if len(not_evaluated) > 3 else "")
        text += (f" {len(not_evaluated)} candidate(s) could not be evaluated (the augmented model could not be solved: "
                 f"{names}); this conclusion does not cover them.")
    return text


def _statement(findings, fit, held_desc: str, above: float | None = None) -> str:
    """The statement's body; ``above``: without a finding, the held-out χ²/N the parameters-only fit leaves when
    above the noise (:func:`statement`), or None."""
    e_par = 100 * fit["parameters_only"]["frf_error_held_out"]
    e_phys = 100 * fit["with_physics"]["frf_error_held_out"]
    e_nom = 100 * fit["nominal"]["frf_error_held_out"]
    if not findings:
        verb = "leaves" if pct(e_nom) == pct(e_par) else "brings"
        head = "beyond parameter error" if above is None else "that the candidate library can name"
        text = (f"Nothing is missing {head}: updating the model's own parameters {verb} the held-out "
                f"FRF error ({held_desc}) {from_to(e_nom, e_par)}, and no candidate physics improves it "
                "further, so none is added.")
        if above is not None:
            text += (f" But the held-out FRFs stay above their noise (χ²/N {above:.3g}; about 1 at the noise): the "
                     "model still leaves something out — its mesh or its sections' scatter (model-form error), or "
                     "physics the library does not hold — so this is no evidence that the model is complete.")
        return text
    by_kind: dict[str, list] = {}
    for f in findings:
        by_kind.setdefault(f.candidate.physics, []).append(f)
    parts = []
    for kind, fs in by_kind.items():
        head, tail = _PHRASES[kind]
        items = " and ".join(_describe(f) for f in fs)
        parts.append(f"{head}: {items}, {tail}.")
    verb = "leaves" if pct(e_par) == pct(e_phys) else "cuts" if e_phys < e_par else "raises"
    return (" ".join(parts) + f" Adding {'them' if len(findings) > 1 else 'it'} {verb} the held-out FRF error "
            f"({held_desc}) {from_to(e_par, e_phys)}; updating the model's own parameters reached "
            f"{pct(e_par)} % (nominal {pct(e_nom)} %).")
