"""Writing output files safely: never over an input, atomically, with the user's umask.

One place for the rules every command that writes files follows (the CLI, ``run`` and stage code call it):

* :func:`check_outputs` refuses, before any work is done, an output that is one of the inputs (even with
  ``force``), an output file that already exists (unless ``force``), a file output that is a folder and a
  folder output that is a file.
* :func:`atomic_path` / :func:`write_text` / :func:`write_bytes` write to a temporary file in the target
  folder and ``os.replace`` it onto the target only when the writing succeeded, so a failure never leaves
  a partial file behind; the file gets the permissions the user's umask gives a new file (``0666 & ~umask``),
  not the 0600 of :func:`tempfile.mkstemp`.
* :func:`write_json` writes a JSON document the same way (indented; numpy scalars and arrays as plain numbers
  and lists), for :meth:`modalab.core.modes.ModeSet.to_json` and the application's JSON outputs.
* :func:`protect` registers input paths for the duration of a command: :func:`atomic_path` (and through it
  every UFF writer of :mod:`modalab.core.uff`) refuses to replace a protected file, whatever called it.
"""
from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import OutputError

__all__ = ["check_outputs", "atomic_path", "write_text", "write_bytes", "write_json", "protect", "check_not_input",
           "file_mode", "same_file"]

_PROTECTED: list[Path] = []


def file_mode() -> int:
    """Permission bits of a new file under the current umask (``0o666 & ~umask``).

    The umask is read from ``/proc/self/status`` where it exists (setting it to read it, the portable way,
    briefly changes it for every thread of the process)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o077)
    os.umask(mask)
    return 0o666 & ~mask


def same_file(a, b) -> bool:
    """True when paths ``a`` and ``b`` name the same file (hard links and symlinks included)."""
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


@contextlib.contextmanager
def protect(paths):
    """Protect the existing files among ``paths`` from being replaced by :func:`atomic_path` inside the block."""
    added = [Path(p) for p in paths if p is not None and Path(p).is_file()]
    _PROTECTED.extend(added)
    try:
        yield
    finally:
        for p in added:
            _PROTECTED.remove(p)


def check_not_input(path) -> None:
    """Raise :class:`OutputError` when ``path`` is a protected input file."""
    for p in _PROTECTED:
        if same_file(p, path):
            raise OutputError(f"'{path}' is an input of this command; an output never overwrites an input. "
                              "Choose another output name")


def check_outputs(inputs=(), files=(), folders=(), *, force: bool = False, writes_into=None,
                  force_option: str | None = "--force") -> None:
    """Refuse unsafe outputs before any work is done.

    ``inputs``: input files; ``files``: output files; ``folders``: output folders;
    ``writes_into``: ``{folder: [file names written into it]}`` to check those against the inputs too.
    An output that is an input is refused even with ``force``; an existing output file only without it.
    ``force_option``: the command's option that sets ``force``, named in the messages (``sim``: ``--overwrite``,
    its ``--force`` is the hammer's); None for a command without one.
    """
    ins = [Path(p) for p in inputs if p is not None]
    for out in (Path(p) for p in files if p is not None):
        for i in ins:
            if same_file(i, out):
                even = f" (not even with {force_option})" if force_option else ""
                raise OutputError(f"output '{out}' is also an input of this command; an output never overwrites "
                                  f"an input{even}. Choose another output name")
        if out.is_dir():
            raise OutputError(f"output '{out}' is a folder; expected a file name (a file inside it, or another "
                              "name)")
        for parent in out.parents:
            if parent.exists():
                if not parent.is_dir():
                    raise OutputError(f"cannot write '{out}': '{parent}' is a file, not a folder")
                break
        if out.exists() and not force:
            todo = f"pass {force_option} to replace it" if force_option else "remove it or choose another name"
            raise OutputError(f"output '{out}' exists; {todo} (inputs are never replaced)")
    for d in (Path(p) for p in folders if p is not None):
        if d.exists() and not d.is_dir():
            raise OutputError(f"output folder '{d}' is a file; expected a folder (it is created when missing)")
        for parent in d.parents:
            if parent.exists():
                if not parent.is_dir():
                    raise OutputError(f"cannot create folder '{d}': '{parent}' is a file, not a folder")
                break
        for i in ins:
            if same_file(i, d):
                raise OutputError(f"output folder '{d}' is also an input of this command; choose another folder")
    for d, names in (writes_into or {}).items():
        if d is None:
            continue
        for name in names:
            target = Path(d) / name
            for i in ins:
                if same_file(i, target):
                    raise OutputError(f"this command writes '{target}', which is one of its inputs; an output "
                                      "never overwrites an input. Choose another output folder")


@contextlib.contextmanager
def atomic_path(path, *, suffix: str | None = None):
    """Yield a temporary path next to ``path``; on success it replaces ``path``, on failure it is removed.

    The parent folder is created when missing.  The temporary name keeps ``path``'s suffix (some writers
    choose the format by it).  Refuses a protected input (:func:`protect`).
    """
    path = Path(path)
    check_not_input(path)
    if path.is_dir():
        raise OutputError(f"output '{path}' is a folder; expected a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=str(path.parent), prefix=f".{path.name}.",
                                   suffix=(path.suffix if suffix is None else suffix) + ".part")
    except OSError as exc:
        raise OutputError(f"cannot write '{path}': {exc.strerror or exc}; check that the folder exists and is "
                          "writable") from None
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (see :func:`atomic_path`)."""
    return write_bytes(path, text.encode(encoding))


def _plain(obj):
    """JSON fallback for numpy scalars and arrays, paths and other objects."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (tuple, set)):
        return list(obj)
    return str(obj)


def write_json(path, doc) -> Path:
    """Write ``doc`` as indented JSON (numpy values as plain numbers) atomically; see :func:`write_bytes`."""
    return write_text(path, json.dumps(doc, indent=1, default=_plain) + "\n")
