"""Pole selection from a stabilisation diagram: automatic clustering or the analyst's choice.

Automatic selection (in the spirit of Neu et al. 2017, "Fully automated
operational modal analysis using multi-stage clustering", MSSP 76)

1. keep the stable poles (frequency, damping and participation tests) that are
   physical: ``0 < ζ ≤ max_damping`` and inside the band (away from its edges);
2. cluster them hierarchically (average linkage) with the distance
   ``d_ij = |f_i−f_j|/max(f_i,f_j) + w_ζ·|ζ_i−ζ_j|/max(ζ_i,ζ_j) + w_mac·(1 − MAC(l_i,l_j))``
   cut at ``distance`` (default 1 %, the frequency stabilisation tolerance);
3. a cluster that holds ``k >= 2`` poles per order over its upper third of orders
   contains ``k`` modes (a close pair is often one merged pole at the lower orders and
   two from some order on, issue 16): its modes are the poles of the upper orders holding
   exactly ``k``, taken rank by rank in frequency (:func:`_resolved_at_upper_orders`), when at
   least ``min_poles`` such orders agree; each is supported by the whole cluster's stability.
   Otherwise a cluster holding two or more poles of the same order in most of its orders is
   split (Ward linkage on frequency and damping) into that many;
4. keep clusters holding stable poles from at least ``min_fraction`` of the evaluated
   orders and at least ``min_poles`` poles: spurious poles are rarely stable over many
   orders; of two kept clusters closer than ``distance/2`` in frequency only the larger
   stays (one physical mode whose estimates wander) — unless they are two modes: they
   hold a pole each at the same orders (more than ``coexist_fraction`` of the orders of the
   smaller: one model order cannot give one mode two poles) or, with several references,
   their participation vectors differ (MAC < ``same_mode_mac``).  A close pair seen by two
   of three references (0.3 % apart, issue 16) is two clusters coexisting at every order;
5. (in :class:`~identification.polymax.PolyMAX`) after LSFD, automatic picks whose shape
   has an MPC below ``min_mpc`` are dropped as noise modes;
6. represent each cluster by the median frequency and damping of its poles in the upper third of
   its orders (estimates converge with the order), with the participation vector of the pole
   closest to that median.

:func:`unresolved_modes` flags a selected mode beside which two consistent, lightly damped poles keep
appearing at the top orders (a pair the order does not yet resolve); :func:`~identification.api.identify`
then tries 1.5 times the default order once.

Manual selection: a list of frequencies in Hz, or a selection file (JSON list,
``{"freq_hz": [...]}``, or TOML ``freq_hz = [...]``); for each, the nearest
stable pole of the highest order that has one within ``manual_tol``.
"""
from __future__ import annotations

import difflib
import json
import logging
import os
import tomllib
from dataclasses import dataclass

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial.distance import squareform

from modalab.core.errors import ModalabValueError, fmt_error
from .stabilisation import StabilisationDiagram, mac_vectors, pole_freq_damping

log = logging.getLogger(__name__)

__all__ = ["SelectionOptions", "SelectedPoles", "select_poles", "auto_select", "select_frequencies",
           "load_selection_file", "order_spread", "unresolved_modes"]


@dataclass(frozen=True)
class SelectionOptions:
    """Settings of the automatic and manual pole selection."""

    distance: float = 0.01          # cut height of the hierarchical clustering
    damping_weight: float = 0.02    # w_ζ in the distance
    mac_weight: float = 0.05        # w_mac in the distance
    min_fraction: float = 0.2       # of the number of evaluated orders
    min_poles: int = 4
    max_damping: float = 0.20       # poles with more damping are unphysical here
    edge_fraction: float = 0.005    # poles within this fraction of the band edges are dropped
    manual_tol: float = 0.02        # relative frequency window for manual picks
    min_mpc: float = 0.5            # after LSFD, automatic picks with a lower MPC are dropped as noise
    max_block: int = 600            # poles clustered at once (bounds the distance matrices to a few MB)
    coexist_fraction: float = 0.5  # near clusters with poles at the same order in more of their orders are two modes
    same_mode_mac: float = 0.9      # near clusters with less participation MAC are two modes (several references)

    def __post_init__(self):
        for name in ("distance", "max_damping", "manual_tol"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0):
                raise ModalabValueError(fmt_error(f"SelectionOptions.{name}", v, "a positive number",
                                                  "Keep the default unless the data call for another"))
        if not (0 <= self.min_fraction <= 1):
            raise ModalabValueError(fmt_error("SelectionOptions.min_fraction", self.min_fraction, "0..1",
                                              "Default 0.2"))


@dataclass
class SelectedPoles:
    """The chosen poles (as estimated, before window correction), sorted by frequency."""

    lam: np.ndarray
    participation: np.ndarray      # (n_in, n_modes)
    order: np.ndarray              # model order of the representative pole
    cluster_size: np.ndarray       # number of stable poles behind each mode (0 for manual picks off-diagram)
    source: str = "auto"
    # spread of the mode's stable poles over the upper third of its orders: standard deviations of their
    # frequencies (Hz) and damping ratios and how many poles they are (:func:`order_spread`); NaN, 0 = none
    freq_spread_hz: np.ndarray | None = None
    damping_spread: np.ndarray | None = None
    n_spread: np.ndarray | None = None

    def __post_init__(self):
        m = self.lam.size
        if self.freq_spread_hz is None:
            self.freq_spread_hz = np.full(m, np.nan)
        if self.damping_spread is None:
            self.damping_spread = np.full(m, np.nan)
        if self.n_spread is None:
            self.n_spread = np.zeros(m, int)

    @property
    def freq_hz(self):
        return pole_freq_damping(self.lam)[0]

    @property
    def damping(self):
        return pole_freq_damping(self.lam)[1]

    def __len__(self):
        return self.lam.size

    def subset(self, idx) -> "SelectedPoles":
        """The poles ``idx`` (indices or a boolean mask), every per-mode field with them."""
        return SelectedPoles(self.lam[idx], self.participation[:, idx], self.order[idx], self.cluster_size[idx],
                             self.source, self.freq_spread_hz[idx], self.damping_spread[idx], self.n_spread[idx])

    def _sorted(self):
        return self.subset(np.argsort(self.freq_hz, kind="stable"))


def _empty(n_in, source):
    return SelectedPoles(np.zeros(0, complex), np.zeros((n_in, 0), complex), np.zeros(0, int), np.zeros(0, int),
                         source)


def _physical(diag: StabilisationDiagram, opts: SelectionOptions, band_hz):
    lo, hi = band_hz if band_hz is not None else (diag.freq_hz.min(initial=0.0), diag.freq_hz.max(initial=np.inf))
    margin = opts.edge_fraction * (hi - lo)
    return ((diag.damping > 0) & (diag.damping <= opts.max_damping)
            & (diag.freq_hz > lo + margin) & (diag.freq_hz < hi - margin))


def _split_block(blk, rel_gap, gap, max_block):
    """Split a contiguous run of frequency-sorted poles at gaps wider than ``gap`` until small enough."""
    if blk.size <= max_block:
        return [blk]
    if gap < 1e-6:
        return np.array_split(blk, int(np.ceil(blk.size / max_block)))
    cuts = np.flatnonzero(rel_gap[blk[:-1]] > gap) + 1
    out = []
    for q in (np.split(blk, cuts) if cuts.size else [blk]):
        out.extend(_split_block(q, rel_gap, gap / 2, max_block))
    return out


def _segment_medians(x, starts, sizes):
    """Medians of the sorted runs ``x[starts[i]:starts[i]+sizes[i]]`` (as ``np.median``: mean of the middle two)."""
    starts = np.asarray(starts)
    sizes = np.asarray(sizes)
    return 0.5 * (x[starts + (sizes - 1) // 2] + x[starts + sizes // 2])


def order_spread(freq_hz, damping):
    """``(std f, std ζ, n)`` of one mode's stable poles over the orders used for its estimate (ddof 1).

    How much the estimate moves with the model order: :class:`~identification.polymax.PolyMAX` adds
    ``spread/√n`` (the standard error of the representative over those orders) to the noise
    standard deviation.  NaN with fewer than two poles.
    """
    f = np.asarray(freq_hz, float)
    z = np.asarray(damping, float)
    if f.size < 2:
        return np.nan, np.nan, int(f.size)
    return float(np.std(f, ddof=1)), float(np.std(z, ddof=1)), int(f.size)


def _mean_participation(Lg):
    """The dominant direction of a cluster's participation vectors (first left singular vector)."""
    if Lg.shape[0] == 1:
        return np.ones(1, complex)
    u, _, _ = np.linalg.svd(Lg, full_matrices=False)
    v = u[:, 0]
    k = int(np.argmax(np.abs(v)))
    return v * (abs(v[k]) / v[k])


def _resolved_at_upper_orders(members, f, od, opts):
    """Order-wise split of a cluster that holds one pole per order below and ``k >= 2`` above.

    Returns ``k`` arrays of pole indices (rank ``r`` in frequency at every resolved order goes to
    mode ``r``), or None.  A cluster is resolved when, over its upper third of orders, most orders hold
    ``k`` poles and at least ``min_poles`` of them hold exactly ``k`` (the resolved orders), and the modes
    stay apart: the robust spread (1.4826 MAD) of each mode's poles is smaller than a quarter of the gap
    between neighbouring modes (converged estimates, not a wandering extra pole).  The poles of the other
    orders (merged below, or one missing or one extra at a noisy order) are left out of the modes.
    """
    orders, cnt = np.unique(od[members], return_counts=True)
    if orders.size < opts.min_poles:
        return None
    upper = orders >= np.percentile(orders, 67)
    k = int(np.round(np.median(cnt[upper])))
    if k < 2:
        return None
    run = orders[upper & (cnt == k)]
    if run.size < opts.min_poles:
        return None
    ranks = [[] for _ in range(k)]
    for n in run:
        at = members[od[members] == n]
        for r, i in enumerate(at[np.argsort(f[at], kind="stable")]):
            ranks[r].append(i)
    modes = [np.array(q) for q in ranks]
    centre = np.array([np.median(f[q]) for q in modes])
    spread = np.array([1.4826 * np.median(np.abs(f[q] - np.median(f[q]))) for q in modes])     # robust std
    gaps = np.diff(centre)
    if np.any(gaps <= 0) or np.any(np.maximum(spread[:-1], spread[1:]) > 0.25 * gaps):
        return None
    return modes


def _same_mode(orders_a, orders_b, la, lb, opts) -> bool:
    """Two near clusters are one mode unless they coexist order by order or their participations differ."""
    shared = len(orders_a & orders_b)
    if shared > opts.coexist_fraction * min(len(orders_a), len(orders_b)):
        return False
    if la.size > 1 and mac_vectors(la[:, None], lb[:, None])[0, 0] < opts.same_mode_mac:
        return False
    return True


def auto_select(diag: StabilisationDiagram, options: SelectionOptions | None = None, *, band_hz=None) -> SelectedPoles:
    """Automatic selection by hierarchical clustering of the stable, physical poles (module docs)."""
    opts = options if options is not None else SelectionOptions()
    n_in = diag.participation.shape[0]
    idx = np.flatnonzero(diag.stable & _physical(diag, opts, band_hz))
    if idx.size < max(opts.min_poles, 2):
        log.warning("automatic selection: only %d stable physical poles; no mode selected", idx.size)
        return _empty(n_in, "auto")
    o = np.argsort(diag.freq_hz[idx])
    idx = idx[o]
    f, z, L, od = diag.freq_hz[idx], diag.damping[idx], diag.participation[:, idx], diag.order[idx]
    lab = _cluster_labels(f, z, L, opts)
    groups, support = _modes_of_clusters(lab, f, z, od, opts)
    sizes = np.array([g.size for g in groups])
    support = np.array(support)
    keep = (sizes >= opts.min_poles) & (support >= opts.min_fraction * diag.orders.size)
    keep = _one_cluster_per_mode(groups, sizes, keep, f, od, L, opts)
    lam, parts, orders, csize, spread = [], [], [], [], []
    for g, ok in zip(groups, keep):
        if not ok:
            continue
        # estimates converge with the order: represent the cluster by its upper third of orders
        top = g[od[g] >= np.percentile(od[g], 67)]
        fm, zm = np.median(f[top]), np.median(z[top])
        score = np.abs(f[top] - fm) / fm + np.abs(z[top] - zm) / max(zm, 1e-12) * 0.01
        best = top[np.argmin(score)]
        # the representative pole: median frequency and damping, participation of the closest pole
        lam.append(complex(-zm * 2 * np.pi * fm, 2 * np.pi * fm * np.sqrt(max(1 - zm ** 2, 0.0))))
        parts.append(L[:, best])
        orders.append(od[best])
        csize.append(g.size)
        spread.append(order_spread(f[top], z[top]))
    log.info("automatic selection: %d stable poles in %d clusters, %d kept", idx.size, len(groups), len(lam))
    if not lam:
        return _empty(n_in, "auto")
    sp_ = np.array(spread, float).reshape(-1, 3)
    return SelectedPoles(np.array(lam), np.array(parts).T, np.array(orders), np.array(csize), "auto",
                         sp_[:, 0], sp_[:, 1], sp_[:, 2].astype(int))._sorted()


def _cluster_labels(f, z, L, opts: SelectionOptions) -> np.ndarray:
    """Cluster label of each pole (frequency-sorted ``f``, ``z``, participations ``L``): average linkage on
    the distance of the module docs, cut at ``distance``, block by block."""
    n_in = L.shape[0]
    # d_ij >= |Δf|/f, so poles separated by a frequency gap wider than the cut never share a cluster:
    # cluster each gap-separated block on its own (memory and time stay per mode, not per diagram)
    rel_gap = np.diff(f) / f[1:]
    blocks = []
    for blk in np.split(np.arange(f.size), np.flatnonzero(rel_gap > opts.distance) + 1):
        # a block crowded with noise poles (very high orders) is split at finer gaps to bound memory
        blocks.extend(_split_block(blk, rel_gap, opts.distance / 2, opts.max_block))
    lab = np.zeros(f.size, int)
    next_label = 1
    for blk in blocks:
        if blk.size == 1:
            lab[blk] = next_label
            next_label += 1
            continue
        fb, zb, Lb = f[blk], z[blk], L[:, blk]
        if n_in == 1:
            # scalar participations: MAC = 1, the distance is symmetric by construction; build
            # the condensed form (pairs i < j, the order of squareform) directly
            i, j = np.triu_indices(blk.size, 1)
            dvec = (np.abs(fb[i] - fb[j]) / np.maximum(fb[i], fb[j])
                    + opts.damping_weight * (np.abs(zb[i] - zb[j]) / np.maximum(zb[i], zb[j])))
        else:
            df = np.abs(fb[:, None] - fb[None, :]) / np.maximum(fb[:, None], fb[None, :])
            dz = np.abs(zb[:, None] - zb[None, :]) / np.maximum(zb[:, None], zb[None, :])
            dm = 1.0 - mac_vectors(Lb, Lb)
            d = df + opts.damping_weight * dz + opts.mac_weight * dm
            d = 0.5 * (d + d.T)
            np.fill_diagonal(d, 0.0)
            dvec = squareform(np.clip(d, 0, None), checks=False)
        sub = fcluster(linkage(dvec, method="average"), t=opts.distance, criterion="distance")
        lab[blk] = sub + next_label
        next_label += sub.max() + 1
    return lab


def _modes_of_clusters(lab, f, z, od, opts: SelectionOptions):
    """``(groups, support)``: the pole indices of each mode the clusters hold (a cluster resolved at its upper
    orders or split by Ward linkage when it holds several poles per order, else itself) and the number of
    stable poles behind each."""
    # clusters as runs of one label: members[starts[c]:starts[c]+counts[c]]
    by_lab = np.argsort(lab, kind="stable")
    labels, starts, counts = np.unique(lab[by_lab], return_index=True, return_counts=True)
    # poles per (cluster, order): the median over the cluster's orders says how many modes it holds
    mult = int(od.max()) + 1
    keys, cnt = np.unique(lab.astype(np.int64) * mult + od, return_counts=True)
    klab = keys // mult
    o2 = np.lexsort((cnt, klab))                                     # by cluster, then count
    _, seg_starts, seg_sizes = np.unique(klab[o2], return_index=True, return_counts=True)
    k_per = _segment_medians(cnt[o2].astype(float), seg_starts, seg_sizes)
    k_all = np.round(k_per).astype(int)
    groups, support = [], []
    for ci in range(labels.size):
        members = by_lab[starts[ci]:starts[ci] + counts[ci]]
        k = k_all[ci]
        log.debug("cluster %d: %d poles, %.6g..%.6g Hz, orders %d..%d, median poles per order %d", ci, members.size,
                  f[members].min(), f[members].max(), od[members].min(), od[members].max(), k)
        resolved = _resolved_at_upper_orders(members, f, od, opts)
        if resolved is not None:
            # k modes at the cluster's upper orders, perhaps one merged pole below (a close pair the lower
            # orders cannot resolve, issue 16): the modes are the poles of the resolved orders, taken rank
            # by rank; the cluster's stability over all its orders supports each of them
            groups.extend(resolved)
            support.extend([members.size] * len(resolved))
            log.info("automatic selection: the cluster at %.5g Hz resolves into %d modes (%s Hz) from order %d on",
                     float(np.median(f[members])), len(resolved),
                     ", ".join(f"{np.median(f[q]):.5g}" for q in resolved), int(min(od[q].min() for q in resolved)))
        elif k >= 2 and members.size >= 2 * k:
            feat = np.column_stack([f[members] / f[members].mean(), 0.1 * z[members] / max(z[members].mean(), 1e-12)])
            sub = fcluster(linkage(feat, method="ward"), t=k, criterion="maxclust")
            parts_ = [members[sub == s] for s in np.unique(sub)]
            groups.extend(parts_)
            support.extend(q.size for q in parts_)
        else:
            groups.append(members)
            support.append(members.size)
    return groups, support


def _one_cluster_per_mode(groups, sizes, keep, f, od, L, opts: SelectionOptions) -> np.ndarray:
    """``keep`` with, of kept clusters nearer than ``distance/2`` that are one mode's wandering estimates
    (:func:`_same_mode`), only the largest left."""
    # one physical mode split into several clusters: keep the largest — but only when the two clusters are
    # one mode's wandering estimates: they rarely hold a pole at the same order (two modes coexist order by
    # order) and, with several references, their participation vectors agree (MAC >= same_mode_mac)
    keep = keep.copy()
    cat = np.concatenate(groups)
    gid = np.repeat(np.arange(len(groups)), sizes)
    o = np.lexsort((f[cat], gid))
    centre = _segment_medians(f[cat][o], np.cumsum(sizes) - sizes, sizes)
    orders_of = [set(od[g].tolist()) for g in groups]
    told = set()                    # pairs of near clusters kept as two modes (logged once)

    Lmean = [_mean_participation(L[:, g]) for g in groups]
    for a in np.argsort(-sizes, kind="stable"):
        if not keep[a]:
            continue
        near = np.flatnonzero(keep & (np.abs(centre - centre[a]) < 0.5 * opts.distance * centre[a]))
        for b in near[near != a]:
            if _same_mode(orders_of[a], orders_of[b], Lmean[a], Lmean[b], opts):
                keep[b] = False
            elif (min(a, b), max(a, b)) not in told:
                told.add((min(a, b), max(a, b)))
                log.info("automatic selection: %.4g and %.4g Hz kept as two modes (they coexist at %d orders; "
                         "participation MAC %.2f)", centre[a], centre[b], len(orders_of[a] & orders_of[b]),
                         float(mac_vectors(Lmean[a][:, None], Lmean[b][:, None])[0, 0]))
    return keep


def unresolved_modes(diag: StabilisationDiagram, selected: SelectedPoles,
                     options: SelectionOptions | None = None, *, band_hz=None) -> np.ndarray:
    """Selected modes that look like a close pair still being resolved at the highest orders.

    For each selected mode, over the last ``max(min_poles, 20 %)`` evaluated orders: an order holds a
    *companion* when, besides the pole nearest the mode, it has another physical pole within
    ``distance/2`` of the mode's frequency, with damping at most ``2 ζ + 0.2 %`` and nearer this mode
    than any other selected mode (the two least damped such poles are the order's pair).  Pairs at
    60 % or more of those orders whose lower and upper frequencies each agree over the orders (standard
    deviation, as 1.4826 MAD, below ``distance/16`` of the mode's frequency, and further apart than that) say the model
    order is just reaching a second mode there (a merged pole below, two poles above, or two poles at
    some orders only: issue 16's close pair at 0.3 %).  Noise poles near a mode are more damped and
    wander from order to order.  Modes within 5 % of the band's width from an edge of ``band_hz`` are
    not judged (the fit puts computational poles near the edges).

    Returns the indices (into ``selected``) of such modes.
    """
    opts = options if options is not None else SelectionOptions()
    if len(selected) == 0 or diag.orders.size == 0:
        return np.zeros(0, int)
    n_top = max(opts.min_poles, int(np.ceil(0.2 * diag.orders.size)))
    top_orders = diag.orders[-n_top:]
    fsel, zsel = selected.freq_hz, selected.damping
    phys = (diag.damping > 0) & (diag.damping <= opts.max_damping)
    lo, hi = band_hz if band_hz is not None else (-np.inf, np.inf)
    edge = 0.05 * (hi - lo) if np.isfinite(hi - lo) else 0.0
    out = []
    for m, (fm, zm) in enumerate(zip(fsel, zsel)):
        if fm < lo + edge or fm > hi - edge:
            continue
        near = phys & (np.abs(diag.freq_hz - fm) < 0.5 * opts.distance * fm) & (diag.damping <= 2 * zm + 0.002)
        if fsel.size > 1:
            # a pole nearer another selected mode belongs to that one
            others = np.delete(fsel, m)
            near &= np.abs(diag.freq_hz - fm) <= np.min(np.abs(diag.freq_hz[:, None] - others[None, :]), axis=1)
        two = []
        for n in top_orders:
            c = np.flatnonzero(near & (diag.order == n))
            if c.size < 2:
                continue
            c = c[np.argsort(diag.damping[c], kind="stable")[:2]]              # the two least damped
            two.append(np.sort(diag.freq_hz[c]))
        two = np.array(two).reshape(-1, 2)
        tol = opts.distance / 16 * fm
        if two.shape[0] < 0.6 * n_top:
            continue
        spread = 1.4826 * np.median(np.abs(two - np.median(two, axis=0)), axis=0)        # robust std
        if np.all(spread < tol) and np.median(two[:, 1] - two[:, 0]) > tol:
            log.debug("mode at %.5g Hz: two poles at %.5g and %.5g Hz (spread %.3g, %.3g Hz) at %d of the last "
                      "%d orders", fm, *np.median(two, axis=0), *spread, two.shape[0], n_top)
            out.append(m)
    return np.array(out, int)


def select_frequencies(diag: StabilisationDiagram, freqs_hz, options: SelectionOptions | None = None) -> SelectedPoles:
    """For each requested frequency the nearest pole of the highest order with a stable pole within ``manual_tol``.

    Falls back to any pole within the window (logged) and raises when none is near.
    """
    opts = options if options is not None else SelectionOptions()
    targets = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if targets.ndim != 1 or not np.all(np.isfinite(targets)) or np.any(targets <= 0):
        raise ModalabValueError(fmt_error("selected frequencies", freqs_hz, "positive frequencies in Hz",
                                          "Give e.g. [12.5, 40.2]"))
    n_in = diag.participation.shape[0]
    lam, parts, orders, csize, spread = [], [], [], [], []
    phys = (diag.damping > 0) & (diag.damping <= opts.max_damping)
    taken = {}                                   # pole index -> the frequency that took it
    for ft in targets:
        near = np.abs(diag.freq_hz - ft) <= opts.manual_tol * ft
        cand = np.flatnonzero(near & diag.stable & phys)
        if cand.size == 0:
            cand = np.flatnonzero(near & phys)
            if cand.size == 0:
                cand = np.flatnonzero(near)
            if cand.size == 0:
                raise ModalabValueError(
                    f"no pole within {100 * opts.manual_tol:.3g} % of {ft:.6g} Hz at any order; "
                    "check the frequency, widen SelectionOptions.manual_tol or raise max_order")
            log.warning("selection at %.6g Hz: no stable pole nearby, taking the nearest unstable one", ft)
        top = diag.order[cand].max()
        c = cand[diag.order[cand] == top]
        best = c[np.argmin(np.abs(diag.freq_hz[c] - ft))]
        if int(best) in taken:
            raise ModalabValueError(
                f"selected frequencies {taken[int(best)]:.6g} Hz and {ft:.6g} Hz both resolve to the pole at "
                f"{diag.freq_hz[best]:.6g} Hz (the nearest pole of the highest order within {100 * opts.manual_tol:.3g} %); "
                "one pole is one mode: give each mode once (look at the stabilisation diagram) or raise max_order")
        taken[int(best)] = ft
        lam.append(diag.lam[best])
        parts.append(diag.participation[:, best])
        orders.append(diag.order[best])
        csize.append(int(np.sum(near & diag.stable)))
        spread.append(_manual_spread(diag, phys, best, opts))
    sp_ = np.array(spread, float).reshape(-1, 3)
    return SelectedPoles(np.array(lam), np.array(parts).T.reshape(n_in, -1), np.array(orders), np.array(csize),
                         "manual", sp_[:, 0], sp_[:, 1], sp_[:, 2].astype(int))._sorted()


def _manual_spread(diag, phys, best, opts):
    """:func:`order_spread` of a manual pick: per order, the stable pole nearest the picked one (within
    ``distance/2``), over the upper third of the orders that have one."""
    fb = diag.freq_hz[best]
    cand = np.flatnonzero(diag.stable & phys & (np.abs(diag.freq_hz - fb) <= 0.5 * opts.distance * fb))
    if cand.size < 2:
        return order_spread([], [])
    pick = []
    for n in np.unique(diag.order[cand]):
        c = cand[diag.order[cand] == n]
        pick.append(c[np.argmin(np.abs(diag.freq_hz[c] - fb))])
    pick = np.array(pick)
    top = pick[diag.order[pick] >= np.percentile(diag.order[pick], 67)]
    return order_spread(diag.freq_hz[top], diag.damping[top])


def load_selection_file(path) -> list[float]:
    """Frequencies (Hz) from a JSON file (list or ``{"freq_hz": [...]}``) or TOML file (``freq_hz = [...]``)."""
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise ModalabValueError(f"selection file {p!r} does not exist; give a JSON or TOML file listing freq_hz")
    try:
        if p.lower().endswith(".toml"):
            with open(p, "rb") as fh:
                data = tomllib.load(fh)
        else:
            with open(p) as fh:
                data = json.load(fh)
    except Exception as e:  # noqa: BLE001 - report any parse failure the same way
        raise ModalabValueError(f"cannot parse selection file {p!r}: {e}. Write a JSON list of Hz, "
                                "{\"freq_hz\": [...]} or TOML 'freq_hz = [...]'") from None
    if isinstance(data, dict) and "freq_hz" not in data:
        other = list(data)
        if other:                    # a misspelt key is named (a modes.json, with freq_hz among others, is fine)
            close = difflib.get_close_matches(other[0], ["freq_hz"], n=1, cutoff=0.5)
            raise ModalabValueError(f"selection file {p!r}: unknown key {other[0]!r}"
                                    + ("; did you mean 'freq_hz'?" if close else "; the only key is freq_hz = [Hz, ...]"))
    vals = data.get("freq_hz") if isinstance(data, dict) else data
    try:
        out = [float(v) for v in vals]
    except (TypeError, ValueError):
        raise ModalabValueError(f"selection file {p!r}: freq_hz must be a list of numbers; got {vals!r}") from None
    if not out:
        raise ModalabValueError(f"selection file {p!r} lists no frequency; add at least one")
    return out


def select_poles(diag: StabilisationDiagram, select="auto", options: SelectionOptions | None = None, *,
                 band_hz=None) -> SelectedPoles:
    """Dispatch: ``'auto'``, a sequence of frequencies (Hz) or a path to a selection file."""
    if isinstance(select, str) and select == "auto":
        return auto_select(diag, options, band_hz=band_hz)
    if isinstance(select, (str, os.PathLike)):
        return select_frequencies(diag, load_selection_file(select), options)
    if np.ndim(select) == 0 and not isinstance(select, (int, float)):
        raise ModalabValueError(fmt_error("select", select, "'auto', frequencies in Hz or a selection-file path",
                                          "Use select='auto' for automatic selection"))
    return select_frequencies(diag, select, options)
