"""The card base class: source location and comment travel with a card but are not compared."""
from __future__ import annotations

from dataclasses import dataclass, field

from modalab.core.errors import BulkDataError

from updating.fe.bulk.fields import RawCard

__all__ = ["Card"]


def _meta():
    return field(default=None, compare=False, repr=False, kw_only=True)


@dataclass
class Card:
    """Base: source location and comment (not compared; keyword-only, so every card's own fields keep their
    positions).  ``from_raw`` fills them with :meth:`_set_meta`."""

    line: int | None = _meta()
    path: str | None = _meta()
    comment: list | None = _meta()

    @property
    def name(self) -> str:
        return self.NAME

    def where(self) -> dict:
        return {"path": self.path, "line": self.line, "card": f"{self.NAME} {self.key()}"}

    def error(self, msg: str) -> BulkDataError:
        return BulkDataError(msg, **self.where())

    def key(self):
        return getattr(self, self.KEY)

    def _set_meta(self, raw: RawCard):
        self.line, self.path, self.comment = raw.line, raw.path, list(raw.comment)
        return self

