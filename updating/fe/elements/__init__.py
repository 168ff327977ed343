"""Element library, one element type per module.

=================  ==============================================================
:class:`Beam3D`     3-D Euler–Bernoulli frame (CBAR-like), orientation vector, consistent/lumped mass
:class:`Timoshenko3D` 3-D shear-deformable frame with rotary inertia
:class:`Beam2D`     planar beam, (w, θ) or (u, w, θ) per node, plane 'xy' or 'xz'
:class:`Rod`        axial + torsion rod (CROD)
:class:`Spring`     scalar spring between two node components or to ground (CELAS)
:class:`Damper`     scalar viscous damper (CDAMP)
:class:`LumpedMass` point mass with rotary inertia and offset (CONM2)
:class:`Quad4`      4-node flat shell, MITC4 bending + incompatible-mode membrane (CQUAD4/PSHELL)
:class:`Tria3`      3-node flat shell, DKT bending + CST membrane (CTRIA3/PSHELL)
=================  ==============================================================
"""
from updating.fe.elements.base import AssemblyContext, Element, ElementMatrices
from updating.fe.elements.beam2d import Beam2D
from updating.fe.elements.beam3d import Beam3D
from updating.fe.elements.damper import Damper
from updating.fe.elements.mass import LumpedMass
from updating.fe.elements.rod import Rod
from updating.fe.elements.shell import Quad4, Tria3
from updating.fe.elements.spring import Spring
from updating.fe.elements.timoshenko3d import Timoshenko3D

__all__ = ["Element", "ElementMatrices", "AssemblyContext", "Beam3D", "Timoshenko3D", "Beam2D", "Rod",
           "Spring", "Damper", "LumpedMass", "Quad4", "Tria3"]
