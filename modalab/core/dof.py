"""Degree-of-freedom labels: a node and a signed direction, ``"12+Z"``.

Directions map to UFF direction codes: X=1, Y=2, Z=3, RX=4, RY=5, RZ=6, with
the sign of the label; a scalar point (no direction) has code 0 and prints as
``"12"``.  ``Dof.parse("12-Z").sign == -1``; data measured at ``12+Z`` and
selected as ``12-Z`` is negated by the containers.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable, Sequence

from .errors import DofError

__all__ = ["Dof", "parse_dofs", "locate", "DIRECTION_NAMES"]

DIRECTION_NAMES = {1: "X", 2: "Y", 3: "Z", 4: "RX", 5: "RY", 6: "RZ"}
_NAME_TO_CODE = {v: k for k, v in DIRECTION_NAMES.items()}
_LABEL = re.compile(r"^\s*(\d+)\s*(?:([+-])\s*(RX|RY|RZ|X|Y|Z|[1-6]))?\s*$", re.IGNORECASE)


@dataclass(frozen=True, order=True)
class Dof:
    """A node id and a signed UFF direction code (-6..6, 0 for a scalar point)."""

    node: int
    direction: int = 0

    def __post_init__(self):
        if not isinstance(self.node, (int,)) or isinstance(self.node, bool):
            try:
                object.__setattr__(self, "node", int(self.node))
            except (TypeError, ValueError):
                raise DofError(f"DOF node {self.node!r} is not an integer; use a node id such as 12") from None
        if self.node < 0:
            raise DofError(f"DOF node {self.node} is negative; node ids are >= 0")
        d = int(self.direction)
        if d < -6 or d > 6:
            raise DofError(
                f"DOF direction code {self.direction!r} is outside -6..6; use +/-1..3 for X,Y,Z, "
                "+/-4..6 for RX,RY,RZ or 0 for a scalar point")
        object.__setattr__(self, "direction", d)

    # ------------------------------------------------------------------ parsing
    @classmethod
    def parse(cls, value) -> "Dof":
        """Parse ``"12+Z"``, ``"12-RX"``, ``"12+3"``, ``"12"`` (scalar), a Dof or ``(node, code)``."""
        if isinstance(value, Dof):
            return value
        if isinstance(value, tuple) and len(value) == 2:
            return cls(int(value[0]), int(value[1]))
        if isinstance(value, str):
            m = _LABEL.match(value)
            if not m:
                raise DofError(
                    f"cannot parse DOF label {value!r}; expected a node id and a signed direction "
                    "such as '12+Z', '7-RX' or '3' for a scalar point")
            node = int(m.group(1))
            if m.group(2) is None:
                return cls(node, 0)
            name = m.group(3).upper()
            code = int(name) if name.isdigit() else _NAME_TO_CODE[name]
            return cls(node, code if m.group(2) == "+" else -code)
        raise DofError(f"cannot interpret {value!r} as a DOF; pass a label such as '12+Z' or a Dof")

    # --------------------------------------------------------------- properties
    @property
    def sign(self) -> int:
        """+1 or -1 (scalar points count as +1)."""
        return -1 if self.direction < 0 else 1

    @property
    def axis(self) -> int:
        """Unsigned direction code 0..6."""
        return abs(self.direction)

    @property
    def uff_code(self) -> int:
        """Signed UFF direction code."""
        return self.direction

    @property
    def positive(self) -> "Dof":
        """The same DOF with a positive direction."""
        return Dof(self.node, self.axis)

    def __neg__(self) -> "Dof":
        return Dof(self.node, -self.direction)

    def same_axis(self, other: "Dof") -> bool:
        """True when both label the same node and axis, whatever the sign."""
        return self.node == other.node and self.axis == other.axis

    @property
    def label(self) -> str:
        if self.direction == 0:
            return str(self.node)
        return f"{self.node}{'+' if self.direction > 0 else '-'}{DIRECTION_NAMES[self.axis]}"

    def __str__(self) -> str:
        return self.label

    def __repr__(self) -> str:
        return f"Dof('{self.label}')"


def parse_dofs(values) -> list[Dof]:
    """Parse one label or a sequence of labels into a list of :class:`Dof`."""
    if isinstance(values, (str, Dof)):
        return [Dof.parse(values)]
    try:
        return [Dof.parse(v) for v in values]
    except TypeError:
        raise DofError(f"cannot interpret {values!r} as DOF labels; pass e.g. ['1+Z', '2+Z']") from None


def locate(dofs: Sequence[Dof], wanted: Iterable, what: str = "DOF",
           where: str = "the data") -> tuple[list[int], list[int]]:
    """Indices and signs of ``wanted`` DOFs within ``dofs`` (sign flips when the labels differ in sign).

    Raises :class:`DofError` naming the missing label, ``where`` it was looked for and what is available.
    """
    table = {}
    for i, d in enumerate(dofs):
        table.setdefault((d.node, d.axis), (i, d.sign))
    idx, sgn = [], []
    for w in parse_dofs(wanted):
        hit = table.get((w.node, w.axis))
        if hit is None:
            avail = ", ".join(str(d) for d in list(dofs)[:12]) + (" ..." if len(dofs) > 12 else "")
            raise DofError(f"{what} {w} is not in {where}; available: {avail}. Check the label or the node numbering")
        idx.append(hit[0])
        sgn.append(hit[1] * w.sign)
    return idx, sgn
