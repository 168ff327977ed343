"""A roving-hammer test of an orthotropic plate, simulated from a finite-difference model (test data generator).

Shares no code with ``identification`` nor with ``roving_lab`` (which builds FRFs by modal
superposition): here the structure is a simply supported orthotropic plate discretised by finite
differences on an ``NX x NY`` grid of point masses (98 DOFs), with Rayleigh damping plus one
discrete dashpot (non-proportional damping: complex modes).  FRFs are not built from modes: the
dynamic stiffness ``M s² + C s + K`` is solved at every line, ``s = iω + β`` (the exponential
window of decay β an analyser applies, on a record long enough for the decay).  Each hammer point
gets ``n_averages`` hits of random strength (half-sine pulse spectrum), the three accelerometers add
a noise floor of their own, and H1 and the coherence are estimated from the averages as an analyser
does (H1 = ΣYX*/Σ|X|², γ² = |ΣYX*|²/(Σ|X|²Σ|Y|²)).  The export is written to UFF dataset 58
with ``pyuff`` (not modalab's writer), accelerometers as responses and hammer points as references
(the analyser's 3 x N orientation) or transposed by reciprocity (N x 3).

The grid is chosen for the hard cases of issue 16: in 0..200 Hz there are 14 modes, among them a
close pair (plate modes (3,2) and (6,1), 0.3 % apart near 125 Hz) that the third accelerometer does
not see (it sits at x = 5/15, nodal for every m multiple of 3, and y = 4/8, nodal for every even n),
and mode (5,2) seen by the first accelerometer only (the second sits at x = 3/15, nodal for m = 5;
the third at y = 4/8).  The dashpot sits at x = 10/15, y = 4/8, nodal for the pair and for (5,2), so
those modes stay invisible where they should while the others become complex.

The true poles are the eigenvalues of the state-space matrix of (M, C, K) (scipy), not a formula.
"""
from __future__ import annotations

import os
import tempfile

import numpy as np
import scipy.linalg as sla

NX, NY = 14, 7                    # interior grid points (simply supported edges at 0 and NX+1 / NY+1)
LX, LY = 1.2, 0.8                 # m
MASS = 12.0                       # kg, spread evenly over the grid points
DXY = 0.8                         # twisting ratio H / sqrt(Dx Dy)
R_DXDY = 0.0771840               # Dx/Dy (puts (3,2) and (6,1) 0.3 % apart)
F_PAIR_HZ = 125.4                 # the pair sits here (sets the stiffness scale)
RAYLEIGH = (1.6, 1.1e-5)          # C = a M + b K
DASHPOT = ((10, 4), 6.0)          # grid point (i, j), 1-based, and its coefficient in N s/m
ACCELS = ((2, 3), (3, 5), (5, 4))  # (i, j) of the three accelerometers; driving points among the hammer points
BETA = 0.139                      # 1/s, the analyser's exponential window
PAIR_MN = ((3, 2), (6, 1))
SINGLE_MN = (5, 2)


def _second_difference(n):
    return 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)


def plate_matrices():
    """(M, C, K) of the grid (DOF k = (j-1)*NX + (i-1) for grid point (i, j), 1-based)."""
    hx, hy = LX / (NX + 1), LY / (NY + 1)
    Ax, Ay = _second_difference(NX) / hx ** 2, _second_difference(NY) / hy ** 2
    Ix, Iy = np.eye(NX), np.eye(NY)
    Lxx, Lyy = np.kron(Iy, Ax), np.kron(Ay, Ix)
    dy = 1.0
    dx = R_DXDY * dy
    hxy = DXY * np.sqrt(dx * dy)
    K = dx * Lxx @ Lxx + 2 * hxy * Lxx @ Lyy + dy * Lyy @ Lyy
    K = 0.5 * (K + K.T)
    n = NX * NY
    M = np.eye(n) * (MASS / n)
    # stiffness scale: the pair's mean frequency at F_PAIR_HZ
    lam_mn = {mn: _sine_eigen(mn, dx, hxy, dy) for mn in PAIR_MN}
    target = (2 * np.pi * F_PAIR_HZ) ** 2
    scale = target / (np.mean(list(lam_mn.values())) / (MASS / n))
    K = K * scale
    a, b = RAYLEIGH
    C = a * M + b * K
    (i, j), c = DASHPOT
    k = _dof(i, j)
    C[k, k] += c
    return M, C, K


def _sine_eigen(mn, dx, hxy, dy):
    m, n = mn
    hx, hy = LX / (NX + 1), LY / (NY + 1)
    ax = (2 - 2 * np.cos(m * np.pi / (NX + 1))) / hx ** 2
    ay = (2 - 2 * np.cos(n * np.pi / (NY + 1))) / hy ** 2
    return dx * ax ** 2 + 2 * hxy * ax * ay + dy * ay ** 2


def _dof(i, j):
    return (j - 1) * NX + (i - 1)


def true_modes(f_max=200.0):
    """(freq_hz, damping, mn) of the modes below ``f_max`` from the state-space eigenvalues.

    ``freq_hz`` is the undamped natural frequency |λ|/2π and ``damping`` = -Re λ/|λ|, the
    convention of the identified poles.  ``mn`` are the half-wave numbers of the real plate
    mode each pole belongs to (largest projection).
    """
    M, C, K = plate_matrices()
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    lam, V = sla.eig(A)
    up = lam.imag > 0
    lam, V = lam[up], V[:n, up]
    o = np.argsort(np.abs(lam))
    lam, V = lam[o], V[:, o]
    f = np.abs(lam) / (2 * np.pi)
    keep = f < f_max
    xs = np.arange(1, NX + 1) / (NX + 1)
    ys = np.arange(1, NY + 1) / (NY + 1)
    mns = []
    for v in V[:, keep].T:
        best, arg = -1.0, None
        for m in range(1, NX + 1):
            for nn in range(1, NY + 1):
                s = np.kron(np.sin(nn * np.pi * ys), np.sin(m * np.pi * xs))
                p = abs(np.vdot(s, v)) / (np.linalg.norm(s) * np.linalg.norm(v))
                if p > best:
                    best, arg = p, (m, nn)
        mns.append(arg)
    return f[keep], -lam.real[keep] / np.abs(lam[keep]), mns


def hammer_points(n_points=74, seed=11):
    """The ``n_points`` grid points the hammer visits (1-based (i, j)), the accelerometer points first."""
    rng = np.random.default_rng(seed)
    allp = [(i, j) for j in range(1, NY + 1) for i in range(1, NX + 1)]
    rest = [p for p in allp if p not in ACCELS]
    pick = rng.choice(len(rest), size=n_points - len(ACCELS), replace=False)
    pts = list(ACCELS) + [rest[k] for k in sorted(pick)]
    return pts


def node_id(p):
    i, j = p
    return 100 * j + i


def roving_export(*, n_points=74, seed=0, n_averages=5, noise=0.02, beta=BETA, f_max=200.0, df=0.125):
    """The analyser's H1 export: dict with ``freq_hz``, ``H`` (3, n_points, F) accelerance (m/s²/N),
    ``coherence``, ``accel_nodes`` and ``hammer_nodes`` (UFF node ids, direction +Z)."""
    M, C, K = plate_matrices()
    pts = hammer_points(n_points)
    ia = [_dof(*p) for p in ACCELS]
    ih = [_dof(*p) for p in pts]
    f = np.arange(df, f_max + df / 2, df)
    s = 2j * np.pi * f + beta
    H = np.empty((3, n_points, f.size), complex)
    for k, sk in enumerate(s):
        X = np.linalg.solve(M * sk ** 2 + C * sk + K, np.eye(M.shape[0])[:, ih])      # receptance columns
        H[:, :, k] = X[ia, :] * sk ** 2
    rng = np.random.default_rng(seed)
    # hammer: half-sine pulse of 1.2 ms (spectrum smooth over 0..200 Hz), peak force varies per hit
    tau = 1.2e-3
    wt = 2 * np.pi * f * tau
    pulse = np.abs(np.cos(wt / 2) / (1 - (wt / np.pi) ** 2))           # |spectrum| of a half-sine, 1 at DC
    amp = rng.uniform(0.6, 1.4, size=(n_points, n_averages))
    Xf = amp[:, :, None] * pulse[None, None, :] * np.exp(1j * rng.uniform(0, 2 * np.pi, (n_points, n_averages, 1)))
    # accelerometer noise floor: per channel, a fraction of its median response level
    floor = noise * np.median(np.abs(H), axis=(1, 2))                  # (3,)
    Nf = (rng.normal(size=(3, n_points, n_averages, f.size)) + 1j * rng.normal(size=(3, n_points, n_averages, f.size)))
    Nf *= floor[:, None, None, None] / np.sqrt(2)
    force_noise = 1e-3 * (rng.normal(size=Xf.shape) + 1j * rng.normal(size=Xf.shape)) / np.sqrt(2)
    Y = H[:, :, None, :] * Xf[None] + Nf                                # (3, n_points, avg, F)
    Xm = Xf + force_noise                                               # the measured force
    Sxy = np.sum(Y * Xm.conj()[None], axis=2)
    Sxx = np.sum(np.abs(Xm) ** 2, axis=1)[None]
    Syy = np.sum(np.abs(Y) ** 2, axis=2)
    H1 = Sxy / Sxx
    coh = np.abs(Sxy) ** 2 / (Sxx * Syy)
    return {"freq_hz": f, "H": H1, "coherence": coh, "accel_nodes": [node_id(p) for p in ACCELS],
            "hammer_nodes": [node_id(p) for p in pts], "beta": beta, "H_exact": H}


def write_uff(path, d, *, orientation="analyser", binary=True):
    """Write the export with pyuff as dataset 58b (``binary``; pyuff's ``mode='add'`` to a new file) or
    ASCII 58, FRF then coherence per pair.

    ``orientation='analyser'``: response = accelerometer, reference = hammer point (3 x N);
    ``'reciprocal'``: response = hammer point, reference = accelerometer (N x 3).
    """
    import pyuff

    f = d["freq_hz"]
    sets = []
    for a, an in enumerate(d["accel_nodes"]):
        for h, hn in enumerate(d["hammer_nodes"]):
            rsp, ref = (an, hn) if orientation == "analyser" else (hn, an)
            common = dict(binary=int(binary), load_case_id=0, rsp_ent_name="PLATE", rsp_node=rsp, rsp_dir=3,
                          ref_ent_name="PLATE", ref_node=ref, ref_dir=3, num_pts=f.size, abscissa_spacing=1,
                          abscissa_min=float(f[0]), abscissa_inc=float(f[1] - f[0]), z_axis_value=0.0,
                          abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz", x=f)
            sets.append(pyuff.prepare_58(
                id1=f"FRF {rsp}:+Z / {ref}:+Z", id2="H1 accelerance", id3="roving hammer", id4="NONE",
                id5="NONE", func_type=4, ord_data_type=6, ordinate_spec_data_type=12,
                ordinate_axis_units_lab="m/s^2", orddenom_spec_data_type=13, orddenom_axis_units_lab="N",
                data=d["H"][a, h], **common))
            sets.append(pyuff.prepare_58(
                id1=f"COH {rsp}:+Z / {ref}:+Z", id2="coherence", id3="roving hammer", id4="NONE",
                id5="NONE", func_type=6, ord_data_type=4, ordinate_spec_data_type=0,
                ordinate_axis_units_lab="NONE", orddenom_spec_data_type=0, orddenom_axis_units_lab="NONE",
                data=d["coherence"][a, h].astype(float), **common))
    # pyuff re-reads the whole file after every set it adds (quadratic in the number of sets): write each
    # set to a new file of its own and concatenate them (a universal file is a sequence of datasets)
    path = str(path)
    with tempfile.TemporaryDirectory() as tmp, open(path, "wb") as out:
        for k, st in enumerate(sets):
            one = os.path.join(tmp, f"{k}.uff")
            if binary:
                pyuff.UFF(one).write_sets(st, mode="add")
            else:
                pyuff.UFF(one).write_sets([st], mode="overwrite")
            with open(one, "rb") as fh:
                out.write(fh.read())
            os.remove(one)
    return path
