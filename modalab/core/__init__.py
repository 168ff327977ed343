"""The core: what every stage shares, and nothing that runs a stage.

DOF labels
    :mod:`.dof` — :class:`Dof`, :func:`parse_dofs`: ``"12+Z"`` ↔ node 12, UFF direction +3.
Containers
    :mod:`.frf` — :class:`FRF`, labelled ``(n_out, n_in, n_freq)`` FRFs with coherence and units;
    :mod:`.records` — :class:`TimeRecord`, one hammer hit, all channels;
    :mod:`.modes` — :class:`ModeSet`, modes on DOF labels (identification → updating).
Structures
    :mod:`.structure` — :class:`Structure` (sparse M, K, C, D with exact FRFs), :class:`ModalModel`.
DAQ configuration
    :mod:`.daqconfig` — channel and acquisition settings shared by the real backend and the simulated lab.
Units and errors
    :mod:`.units`; :mod:`.errors` — :class:`ModalabError` and its subclasses.
Files
    :mod:`.uff` — universal file I/O (15, 2411, 55, 58/58b, 164); :mod:`.lvm` — LabVIEW text records.
Figures
    :mod:`.plots` — FRF, hit and geometry figures of core data.

Layers, bottom up: ``modalab.core`` → ``acquisition`` | ``hardware_sim`` → ``identification`` →
``updating`` → ``modalab.app`` (the command line, stages, project runs, campaigns, report, demo).
The import-linter contracts in ``pyproject.toml`` check it.
"""
from . import uff  # noqa: F401,E402  (attaches FRF/ModeSet.from_uff and to_uff: the reader depends on the containers)
