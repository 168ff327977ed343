"""Coordinate systems of bulk data (CORD2R, CORD2C, CORD2S) resolved into the basic system.

A system is an origin ``o`` and a rotation ``R`` whose columns are its axes in
basic.  Points given in a system (GRID CP, CONM2 CID) are converted by
``to_basic``: rectangular (x, y, z); cylindrical (r, θ°, z); spherical
(r, θ°, φ°) with θ from the z axis.  Displacement directions (GRID CD) are
the local axes ``axes_at(point)``: for cylindrical systems (e_r, e_θ, e_z) and
for spherical (e_r, e_θ, e_φ) at the point, as Nastran defines them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import BulkDataError

__all__ = ["CoordSystem", "BASIC", "resolve_coord"]


@dataclass(frozen=True)
class CoordSystem:
    """A resolved coordinate system: ``kind`` 'R', 'C' or 'S', origin and axes (columns) in basic."""

    cid: int
    kind: str
    origin: np.ndarray
    R: np.ndarray

    def local_cartesian(self, p) -> np.ndarray:
        p = np.asarray(p, float)
        if self.kind == "R":
            return p
        if self.kind == "C":
            r, th, z = p[0], np.radians(p[1]), p[2]
            return np.array([r * np.cos(th), r * np.sin(th), z])
        r, th, ph = p[0], np.radians(p[1]), np.radians(p[2])
        return np.array([r * np.sin(th) * np.cos(ph), r * np.sin(th) * np.sin(ph), r * np.cos(th)])

    def to_basic(self, p) -> np.ndarray:
        """Basic coordinates of the point ``p`` given in this system."""
        return self.origin + self.R @ self.local_cartesian(p)

    def from_basic(self, x) -> np.ndarray:
        """Coordinates in this system of the basic point ``x``."""
        q = self.R.T @ (np.asarray(x, float) - self.origin)
        if self.kind == "R":
            return q
        if self.kind == "C":
            return np.array([np.hypot(q[0], q[1]), np.degrees(np.arctan2(q[1], q[0])), q[2]])
        r = float(np.linalg.norm(q))
        th = np.degrees(np.arccos(q[2] / r)) if r > 0 else 0.0
        return np.array([r, th, np.degrees(np.arctan2(q[1], q[0]))])

    def axes_at(self, x_basic) -> np.ndarray:
        """3×3 rotation (columns = displacement axes in basic) at the basic point ``x_basic``."""
        if self.kind == "R":
            return self.R
        q = self.R.T @ (np.asarray(x_basic, float) - self.origin)
        ph = np.arctan2(q[1], q[0])
        c, s = np.cos(ph), np.sin(ph)
        if self.kind == "C":
            L = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        else:
            r = np.linalg.norm(q)
            th = np.arccos(np.clip(q[2] / r, -1, 1)) if r > 0 else 0.0
            ct, st = np.cos(th), np.sin(th)
            L = np.array([[st * c, ct * c, -s], [st * s, ct * s, c], [ct, -st, 0.0]])
        return self.R @ L


BASIC = CoordSystem(0, "R", np.zeros(3), np.eye(3))


def resolve_coord(bulk, cid: int, _stack=()) -> CoordSystem:
    """Resolve system ``cid`` of ``bulk`` (through its RID chain) into the basic system."""
    if cid == 0:
        return BASIC
    card = bulk.coords.get(cid)
    if card is None:
        raise BulkDataError(f"coordinate system {cid} is not defined; add a CORD2R/C/S card with CID {cid}")
    if cid in _stack:
        raise card.error(f"coordinate systems {' -> '.join(map(str, _stack + (cid,)))} refer to each other in "
                         "a cycle; one of them must be defined relative to the basic system (RID 0)")
    if card.rid and card.rid not in bulk.coords:
        raise card.error(f"RID = {card.rid} refers to an undefined coordinate system")
    ref = resolve_coord(bulk, card.rid, _stack + (cid,))
    a, b, c = (ref.to_basic(p) for p in (card.a, card.b, card.c))
    ez = b - a
    nz = np.linalg.norm(ez)
    if not nz > 0:
        raise card.error(f"points A {card.a} and B {card.b} coincide; B must lie on the local z axis away from "
                         "the origin A")
    ez = ez / nz
    ey = np.cross(ez, c - a)
    ny = np.linalg.norm(ey)
    if not ny > 1e-12 * max(nz, np.linalg.norm(c - a), 1e-300):
        raise card.error(f"point C {card.c} lies on the z axis through A and B; C must define the x-z plane")
    ey = ey / ny
    ex = np.cross(ey, ez)
    return CoordSystem(cid, card.kind, a, np.column_stack([ex, ey, ez]))
