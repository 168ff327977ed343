"""3-D Timoshenko frame element: shear deformation and rotary inertia.

Same nodes, DOFs and orientation as :class:`~updating.fe.elements.beam3d.Beam3D`;
bending uses the interdependent-interpolation element of Friedman & Kosmatka
(1993) with φ = 12 E I / (κ G A L²) per plane, whose consistent mass includes
rotary inertia ρI.  A section without shear factors (``ky``/``kz`` None)
behaves as shear-rigid in that plane (rotary inertia is still included).

Lumped mass (no PARAM,COUPMASS): as Nastran's CBEAM, half the translational mass and half the torsional
inertia ρ·Ip·L at each end (MSC Nastran QRG, PARAM,COUPMASS: the lumped mass matrices "may include torsion
inertia for beam elements"; Autodesk Nastran: "the diagonal mass matrix formulation includes rotary inertia
terms").  Without it a free-free lumped CBEAM deck has five rigid modes and a massless rigid torsion
instead of six rigid modes.  A CBAR with shear factors, also built as this class, sets ``lumped_torsion``
False (Nastran's lumped CBAR mass is translational only).
"""
from __future__ import annotations

from dataclasses import dataclass

from updating.fe.elements.beam3d import Beam3D

__all__ = ["Timoshenko3D"]


@dataclass
class Timoshenko3D(Beam3D):
    """Shear-deformable 3-D beam (see :class:`Beam3D` for the arguments)."""

    _shear = True
    _lumped_torsion = True          # the element of a CBEAM: Nastran's lumped CBEAM mass has torsional inertia
