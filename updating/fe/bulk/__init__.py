"""Nastran bulk-data import and export for FE correlation and updating.

Reading
-------
``read_bdf(path_or_text, xref=True, base_dir=None)`` → :class:`BulkData`
    whole SOL 103 decks (executive/case control recognised and skipped, SPC/METHOD/SDAMPING
    selections kept), INCLUDE, ENDDATA; small, large (``*``) and free (comma) fields with
    explicit or implicit continuations.  Unsupported cards are kept and listed in one
    :class:`UnsupportedCardWarning`; a misspelt card name (``CBAT`` for ``CBAR``: close to a known
    Nastran card, :mod:`~updating.fe.bulk.card_names`) is an error unless ``ignore_unsupported=True``.  Every error is a :class:`modalab.core.errors.BulkDataError`
    naming the card, line and file.
:class:`BulkData`
    ``grids``, ``coords``, ``elements``, ``rigid``, ``properties``, ``materials``, ``spcs``,
    ``spcadds``, ``params``, ``tables``, ``eigrls``, ``unsupported``, ``case_control``;
    ``check()`` cross-references, ``grid_xyz(nid)``, ``coord_system(cid)``, ``count()``.

Building and exporting
----------------------
``build_model(bulk, spc_id=None, sdamping=None, name=None)`` → :class:`updating.fe.FEModel`
    (COUPMASS lumped/coupled mass, GE and PARAM G hysteretic damping, WTMASS, CP/CD systems,
    TABDMP1 modal damping; see :mod:`updating.fe.bulk.build`).
``to_bulk(model, template=None)`` → :class:`BulkData` of an (updated) FE model, keeping the
    template's unchanged cards.
``write_bdf(bulk_or_model, path=None, format='small'|'large'|'free', exact=True)`` → text.

Pieces
------
:mod:`~updating.fe.bulk.fields` (``parse_real``, ``parse_int``, ``format_real``, ``group_cards``,
``card_lines``), :mod:`~updating.fe.bulk.cards` (typed cards, ``section_properties`` of
PBARL/PBEAML sections), :mod:`~updating.fe.bulk.geometry` (CORD2R/C/S).
"""
from updating.fe.bulk.build import build_model, section_of
from updating.fe.bulk.cards import SECTION_DIMS, section_properties
from updating.fe.bulk.fields import RawCard, format_real, parse_int, parse_real
from updating.fe.bulk.geometry import CoordSystem, resolve_coord
from updating.fe.bulk.reader import BulkData, CaseControl, UnsupportedCardWarning, read_bdf
from updating.fe.bulk.writer import card_text, to_bulk, write_bdf

__all__ = ["read_bdf", "BulkData", "CaseControl", "UnsupportedCardWarning", "build_model", "section_of",
           "to_bulk", "write_bdf", "card_text", "parse_real", "parse_int", "format_real", "RawCard",
           "section_properties", "SECTION_DIMS", "CoordSystem", "resolve_coord"]
