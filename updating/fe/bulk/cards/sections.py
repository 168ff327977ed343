"""The PBARL/PBEAML cross-section library (MSC/NX conventions): :func:`section_properties`
gives A, I1, I2, I12, J of a named section from its dimensions."""
from __future__ import annotations

import math

from modalab.core.errors import BulkDataError


__all__ = ["SECTION_DIMS", "SUPPORTED_SECTIONS", "section_properties"]


SECTION_DIMS = {"ROD": 1, "TUBE": 2, "TUBE2": 2, "I": 6, "CHAN": 4, "T": 4, "BOX": 4, "BAR": 2, "CROSS": 4,
                "H": 4, "T1": 4, "I1": 4, "CHAN1": 4, "Z": 4, "CHAN2": 4, "T2": 4, "BOX1": 6, "HEXA": 3,
                "HAT": 4, "HAT1": 5, "DBOX": 10, "L": 4}


SUPPORTED_SECTIONS = ("ROD", "TUBE", "BAR", "BOX", "I")


def _rect_J(a: float, b: float) -> float:
    """Saint-Venant torsion constant of a solid a×b rectangle (Roark), as updating.fe's RectangularSection."""
    a, c = (a, b) if a >= b else (b, a)
    r = c / a
    return a * c ** 3 * (1.0 / 3.0 - 0.21 * r * (1.0 - r ** 4 / 12.0))


def section_properties(kind: str, dims) -> dict:
    """A, I1, I2, J (and shear factors k1, k2) of a PBARL/PBEAML section.

    I1 bends in plane 1 (about element z; element y along DIM2 of BAR and BOX,
    along the web DIM1 of I), I2 in plane 2.  Formulas:

    * BAR  (DIM1 = b along z, DIM2 = h along y): A = bh, I1 = b h³/12, I2 = h b³/12,
      J (Roark) = a c³ [1/3 − 0.21 (c/a)(1 − (c/a)⁴/12)], a ≥ c the sides; k = 5/6.
    * ROD  (DIM1 = r): A = πr², I1 = I2 = πr⁴/4, J = πr⁴/2.
    * TUBE (DIM1 = r_o, DIM2 = r_i): A = π(r_o²−r_i²), I = π(r_o⁴−r_i⁴)/4, J = 2I.
    * BOX  (DIM1 = b, DIM2 = h, DIM3 = t of the walls across h, DIM4 = t of the walls across b):
      A = bh − b_i h_i, I1 = (b h³ − b_i h_i³)/12, I2 = (h b³ − h_i b_i³)/12 with
      b_i = b − 2·DIM4, h_i = h − 2·DIM3; Bredt's J = 2 t₃ t₄ (b−t₄)² (h−t₃)² / (b t₄ + h t₃ − t₄² − t₃²);
      shear areas: the walls parallel to each shear direction.
    * I    (DIM1 = depth h along y, DIM2/DIM3 = bottom/top flange widths, DIM4 = web
      thickness, DIM5/DIM6 = bottom/top flange thicknesses): parallel-axis theorem about
      the centroid; open-section J = (DIM2·DIM5³ + DIM3·DIM6³ + (h−DIM5−DIM6)·DIM4³)/3;
      k1 = web area / A (shear along the web), k2 = (5/6)·flange area / A.
    """
    k = kind.upper()
    d = [float(v) for v in dims]
    need = SECTION_DIMS.get(k)
    if need is None:
        raise BulkDataError(f"unknown section type {kind!r}; known types: {', '.join(SECTION_DIMS)}")
    if len(d) != need:
        raise BulkDataError(f"section {k} needs {need} dimensions; got {len(d)}")
    if any(not v > 0 for v in d):
        raise BulkDataError(f"section {k} dimensions {d}; every DIMi must be > 0")
    if k == "BAR":
        b, h = d
        return {"A": b * h, "I1": b * h ** 3 / 12, "I2": h * b ** 3 / 12, "J": _rect_J(b, h),
                "k1": 5 / 6, "k2": 5 / 6}
    if k == "ROD":
        r = d[0]
        I = math.pi * r ** 4 / 4
        return {"A": math.pi * r * r, "I1": I, "I2": I, "J": 2 * I, "k1": 0.9, "k2": 0.9}
    if k == "TUBE":
        ro, ri = d
        if not ri < ro:
            raise BulkDataError(f"TUBE inner radius DIM2 = {ri} must be smaller than the outer DIM1 = {ro}")
        I = math.pi * (ro ** 4 - ri ** 4) / 4
        return {"A": math.pi * (ro ** 2 - ri ** 2), "I1": I, "I2": I, "J": 2 * I, "k1": 0.5, "k2": 0.5}
    if k == "BOX":
        b, h, t3, t4 = d
        bi, hi = b - 2 * t4, h - 2 * t3
        if not (bi > 0 and hi > 0):
            raise BulkDataError(f"BOX walls too thick: DIM1 = {b} must exceed 2·DIM4 = {2 * t4} and DIM2 = {h} "
                                f"2·DIM3 = {2 * t3}")
        A = b * h - bi * hi
        J = 2 * t3 * t4 * (b - t4) ** 2 * (h - t3) ** 2 / (b * t4 + h * t3 - t4 ** 2 - t3 ** 2)
        return {"A": A, "I1": (b * h ** 3 - bi * hi ** 3) / 12, "I2": (h * b ** 3 - hi * bi ** 3) / 12, "J": J,
                "k1": 2 * h * t4 / A, "k2": 2 * b * t3 / A}
    if k == "I":
        h, wb, wt, tw, tb, tt = d
        hw = h - tb - tt
        if not hw > 0:
            raise BulkDataError(f"I section: flange thicknesses DIM5 + DIM6 = {tb + tt} must be below the depth "
                                f"DIM1 = {h}")
        parts = [(wb * tb, tb / 2, wb * tb ** 3 / 12), (hw * tw, tb + hw / 2, tw * hw ** 3 / 12),
                 (wt * tt, h - tt / 2, wt * tt ** 3 / 12)]
        A = sum(p[0] for p in parts)
        yc = sum(p[0] * p[1] for p in parts) / A
        I1 = sum(p[2] + p[0] * (p[1] - yc) ** 2 for p in parts)
        I2 = (tb * wb ** 3 + hw * tw ** 3 + tt * wt ** 3) / 12
        J = (wb * tb ** 3 + wt * tt ** 3 + hw * tw ** 3) / 3
        return {"A": A, "I1": I1, "I2": I2, "J": J, "k1": hw * tw / A, "k2": 5 / 6 * (wb * tb + wt * tt) / A}
    raise BulkDataError(f"section type {k} is read but its properties are not implemented; supported: "
                        f"{', '.join(SUPPORTED_SECTIONS)}. Convert it to PBAR/PBEAM")

