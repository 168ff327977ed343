"""Exception hierarchy of modalab.

Every exception raised on purpose by modalab derives from :class:`ModalabError`.
Where an error refines a built-in category it also subclasses that built-in
(``DofError`` is a ``ValueError``), so callers' ``except ValueError`` keeps
working.  Messages name the bad value, what was expected and what to do next;
:func:`fmt_error` helps keep that shape uniform.
"""
from __future__ import annotations

__all__ = [
    "ModalabError",
    "ModalabValueError",
    "DofError",
    "ShapeError",
    "UffError",
    "BulkDataError",
    "NotFittedError",
    "ConvergenceError",
    "PlanError",
    "DaqError",
    "DaqTimeoutError",
    "DaqNotFoundError",
    "DeviceLostError",
    "SerialProtocolError",
    "StoreError",
    "OutputError",
    "fmt_error",
]


def fmt_error(what: str, got: object, expected: str, fix: str) -> str:
    """Compose a message of the form ``what: got X; expected Y. Fix.``"""
    return f"{what}: got {got!r}; expected {expected}. {fix}"


class ModalabError(Exception):
    """Root of every error modalab raises on purpose."""


class ModalabValueError(ModalabError, ValueError):
    """An argument has the wrong value or shape."""


class DofError(ModalabValueError):
    """A DOF label cannot be parsed or is not present in the data."""


class ShapeError(ModalabValueError):
    """Array dimensions do not agree with each other or with the labels."""


def _where(*parts) -> str:
    """'file 'x', dataset 58, line 12: ' from (name, value) pairs whose value is known."""
    where = [f"{name} {str(v)!r}" if name == "file" else f"{name} {v}" for name, v in parts if v is not None]
    return (", ".join(where) + ": ") if where else ""


class UffError(ModalabError, ValueError):
    """A universal file is malformed, truncated or cannot be written.

    Attributes ``path``, ``dataset`` and ``line`` locate the problem when known.
    """

    def __init__(self, message: str, *, path=None, dataset=None, line=None):
        super().__init__(_where(("file", path), ("dataset", dataset), ("line", line)) + message)
        self.path, self.dataset, self.line = path, dataset, line


class BulkDataError(ModalabError, ValueError):
    """Nastran bulk data is malformed; names the card and the line."""

    def __init__(self, message: str, *, path=None, card=None, line=None):
        super().__init__(_where(("file", path), ("line", line), ("card", card)) + message)
        self.path, self.card, self.line = path, card, line


class NotFittedError(ModalabError, AttributeError):
    """An estimator was used before ``fit`` was called."""


class ConvergenceError(ModalabError, RuntimeError):
    """An iterative method did not converge within its limits."""


class PlanError(ModalabValueError):
    """A test plan or project file is invalid."""


class DaqError(ModalabError, RuntimeError):
    """A data-acquisition device reported an error."""


class DaqTimeoutError(DaqError, TimeoutError):
    """No triggered record arrived in time: no hit yet."""


class DaqNotFoundError(ModalabError, RuntimeError):
    """The DAQ driver is not installed.  Deliberately *not* a :class:`DaqError`."""


class DeviceLostError(DaqError):
    """The device disappeared during a record."""


class SerialProtocolError(ModalabError, RuntimeError):
    """A serial instrument replied with something its protocol does not allow."""


class StoreError(ModalabError, RuntimeError):
    """An acquisition store on disk is inconsistent."""


class OutputError(ModalabValueError):
    """An output path is unsafe or unwritable: it is an input, it exists (without ``--force``), it is a
    folder where a file is expected (or the reverse), or its folder cannot be written."""
