"""3-D Timoshenko frame element: shear deformation and rotary inertia.

Same nodes, DOFs and orientation as :class:`~updating.fe.elements.beam3d.Beam3D`;
bending uses the interdependent-interpolation element of Friedman & Kosmatka
(1993) with φ = 12 E I / (κ G A L²) per plane, whose consistent mass includes
rotary inertia ρI.  A section without shear factors (``ky``/``kz`` None)
behaves as shear-rigid in that plane (rotary inertia is still included).

Lumped mass (no PARAM,COUPMASS): as Nastran's CBEAM, half the translational mass and half the torsional
inertia ρ·Ip·L at each end (Autodesk Nastran reference, PARAM,COUPMASS: the diagonal mass matrix is the
coupled one's diagonal scaled to the element mass, and "includes rotary inertia terms",
https://help.autodesk.com/cloudhelp/2020/ITA/NSTRN-Reference/files/GUID-F96EEE43-1AF8-44B9-B766-0BD4CA65054B.htm;
we did not find MSC's wording).  Without it a free-free lumped CBEAM deck has five rigid modes and a
massless rigid torsion instead of six rigid modes.  A CBAR with shear factors, also built as this class, sets
``lumped_torsion`` False: the source above does not say what CBAR's diagonal mass holds, and CBAR stays as it
was (translational lumped mass only) — an assumption, not a documented Nastran rule.
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
