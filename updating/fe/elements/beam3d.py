"""3-D Euler–Bernoulli frame element (Nastran CBAR, with rigid end offsets; no pin flags).

Two nodes, 6 DOFs each in the basic system; axial, torsion and bending in two
planes.  Consistent mass (cubic Hermite bending, linear axial and torsional
shapes, as Nastran's coupled CBAR mass) or lumped mass when the model's
``coupled_mass`` is False (PARAM COUPMASS): half the translational mass at each end, and for a CBEAM
(``lumped_torsion``) half the torsional inertia ρ·Ip·L too.  Stiffness:
Przemieniecki, *Theory of Matrix Structural Analysis* (1968), eq. 5.115.

End offsets (CBAR WA/WB) are rigid: the beam runs between x_A + w_A and
x_B + w_B, and its end motion is u_end = u_grid + θ_grid × w, i.e.
K_grid = Wᵀ K_end W with W = [[I, −[w]×], [0, I]] per end.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modalab.core.errors import ModalabValueError

from updating.fe.elements._frame import frame_local_batch, local_axes, local_axes_batch, to_basic
from updating.fe.elements.base import Element, ElementMatrices, six_dofs
from updating.fe.properties import BeamProperty

__all__ = ["Beam3D"]


@dataclass
class Beam3D(Element):
    """Euler–Bernoulli 3-D beam.

    eid : element id.  n1, n2 : end nodes A and B.  pid : id of a
    :class:`~updating.fe.properties.BeamProperty`.  orientation : the vector v
    (basic system) or the id of a node G0 (v = x(G0) − x(A)); local y lies in
    the plane of the beam axis and v.  offset_a, offset_b : rigid end offsets
    (m, basic system) from grid A/B to the beam's end (Nastran WA/WB after
    rotation to basic); the orientation vector from G0 is taken from grid A.
    """

    eid: int
    n1: int
    n2: int
    pid: int
    orientation: object = (0.0, 0.0, 1.0)
    offset_a: object = None
    offset_b: object = None
    #: lumped mass (no COUPMASS) with the torsional inertia ρ·Ip·L/2 at each end, as Nastran's CBEAM; None:
    #: the class default (:class:`Timoshenko3D`, which the bulk data reader builds for CBEAM: yes; Beam3D: no)
    lumped_torsion: bool | None = None

    frame = "basic"
    _shear = False
    _lumped_torsion = False

    @property
    def nodes(self) -> tuple:
        return (self.n1, self.n2)

    def dofs(self) -> list:
        return six_dofs(self.nodes)

    def axes(self, ctx):
        x1, x2 = ctx.xyz(self.n1), ctx.xyz(self.n2)
        v = self.orientation
        if np.ndim(v) == 0:
            v = ctx.xyz(int(v)) - x1
        wa = np.zeros(3) if self.offset_a is None else np.asarray(self.offset_a, float)
        wb = np.zeros(3) if self.offset_b is None else np.asarray(self.offset_b, float)
        return local_axes(x1 + wa, x2 + wb, v, self.eid)

    def matrices(self, ctx) -> ElementMatrices:
        K, M, ge = type(self).batch_matrices([self], ctx)
        return ElementMatrices(self.dofs(), K=K[0], M=M[0], ge=ge[0])

    @classmethod
    def batch_matrices(cls, elements, ctx):
        """(K, M, ge) of many elements of this class: (n, 12, 12), (n, 12, 12), (n,) in basic axes."""
        n = len(elements)
        x1 = np.empty((n, 3))
        x2 = np.empty((n, 3))
        v = np.empty((n, 3))
        pids = np.empty(n, dtype=np.int64)
        offset = []
        for k, el in enumerate(elements):
            x1[k] = ctx.xyz(el.n1)
            x2[k] = ctx.xyz(el.n2)
            o = el.orientation
            v[k] = ctx.xyz(int(o)) - x1[k] if np.ndim(o) == 0 else o
            pids[k] = el.pid
            if el.offset_a is not None or el.offset_b is not None:
                wa = np.zeros(3) if el.offset_a is None else np.asarray(el.offset_a, float)
                wb = np.zeros(3) if el.offset_b is None else np.asarray(el.offset_b, float)
                if wa.shape != (3,) or wb.shape != (3,):
                    raise ModalabValueError(f"element {el.eid}: offsets {el.offset_a!r}, {el.offset_b!r}; "
                                            "expected three components each (m, basic system)")
                x1[k] += wa
                x2[k] += wb
                offset.append((k, wa, wb))
        L, lam = local_axes_batch(x1, x2, v, [el.eid for el in elements])
        names = ("E", "G", "EG", "rho", "A", "Iy", "Iz", "J", "Ip", "nsm", "ky", "kz", "ge")
        cols = {nm: [None] * n for nm in names}
        uniq, inv = np.unique(pids, return_inverse=True)
        for u, pid in enumerate(uniq):
            prop = ctx.prop(int(pid))
            if not isinstance(prop, BeamProperty):
                bad = elements[int(np.flatnonzero(inv == u)[0])]
                raise ModalabValueError(f"element {bad.eid} ({cls.__name__}) refers to property {pid}, a "
                                        f"{type(prop).__name__}; a beam needs a BeamProperty")
            mat = ctx.material(prop.mid)
            s = prop.section
            # E/G exactly 2(1+ν) where G is derived from E (frame_local_batch's e_over_g)
            eg = 2.0 * (1.0 + mat.nu) if mat.G is None else mat.E / mat.G
            vals = dict(E=mat.E, G=mat.shear_modulus, EG=eg, rho=mat.rho, A=s.A, Iy=s.Iy, Iz=s.Iz, J=s.J,
                        Ip=s.polar, nsm=prop.nsm, ky=s.ky, kz=s.kz, ge=prop.ge if prop.ge is not None else mat.ge)
            for nm in names:
                cols[nm][u] = vals[nm]
        arr = {}
        for nm in names:
            per = cols[nm][:len(uniq)]
            if nm in ("ky", "kz"):
                if not cls._shear or any(x is None for x in per):
                    # shear-rigid where no factor is given
                    per = [0.0 if x is None else x for x in per]
                    if not cls._shear:
                        arr[nm] = None
                        continue
            a = np.asarray(per)
            arr[nm] = a[inv]
        ky, kz = arr["ky"], arr["kz"]   # 0 marks a shear-rigid plane
        Kl, Ml = frame_local_batch(L, arr["E"], arr["G"], arr["rho"], arr["A"], arr["Iy"], arr["Iz"], arr["J"],
                                   arr["Ip"], arr["nsm"], shear_y=ky, shear_z=kz, lumped=not ctx.coupled_mass,
                                   rotary=cls._shear, e_over_g=arr["EG"],
                                   lumped_torsion=np.array([cls._lumped_torsion if el.lumped_torsion is None
                                                            else bool(el.lumped_torsion) for el in elements]))
        K, M = to_basic(Kl, lam), to_basic(Ml, lam)
        for k, wa, wb in offset:
            W = np.eye(12)
            W[0:3, 3:6] = -_skew(wa)
            W[6:9, 9:12] = -_skew(wb)
            K[k] = W.T @ K[k] @ W
            M[k] = W.T @ M[k] @ W
        return K, M, arr["ge"]


def _skew(r):
    x, y, z = r
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
