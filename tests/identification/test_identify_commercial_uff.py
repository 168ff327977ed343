"""A UFF with FRFs written the way commercial software exports them identifies without edits.

The file is built line by line in the layout of a Simcenter Testlab ASCII export (CRLF line ends,
dataset 151 header and 164 units first, ``H1_<node>:<dir>/<node>:<dir>`` ID lines, complex single
precision ordinates (type 5) in 6E13.5 fields, signed directions), so nothing of modalab's own writer
is involved; ``modalab identify`` then reads and identifies it.
"""
import numpy as np

from identification import identify
from identification.synthetic import modal_system
from modalab.app.cli import main
from modalab.core.frf import FRF


def _e13(v):
    return f"{v:13.5E}"


def _testlab_ascii(freq, H, responses, ref):
    lines = ["    -1", "   151", "Model1", "NONE", "Simcenter Testlab", "12-Jun-23 10:11:12", "12-Jun-23 10:11:12",
             "Simcenter Testlab Universal File Export", "12-Jun-23 10:11:12", "    -1",
             "    -1", "   164", "         1SI - mks (Newton)           2",
             "  1.00000000000000000D+00  1.00000000000000000D+00  1.00000000000000000D+00",
             "  2.73150000000000000D+02", "    -1"]
    df = freq[1] - freq[0]
    for k, (node, d) in enumerate(responses):
        vals = np.empty(2 * freq.size)
        vals[0::2], vals[1::2] = H[k].real, H[k].imag
        lines += ["    -1", "    58", f"H1_{node}:{'+' if d > 0 else '-'}Z/{ref}:+Z", "NONE", "12-Jun-23 10:11:12",
                  f"Point{node}", "NONE",
                  f"    4{k + 1:10d}    0         0 NONE      {node:10d}{d:4d} NONE      {ref:10d}   3",
                  f"         5{freq.size:10d}         1{_e13(freq[0])}{_e13(df)}  0.00000E+00",
                  "        18    0    0    0 Frequency            Hz",
                  "        12    1    0    0 Acceleration         m/s2",
                  "        13    0    1    0 Force                N",
                  "         0    0    0    0 NONE                 NONE"]
        for a in range(0, vals.size, 6):
            lines.append("".join(_e13(v) for v in vals[a:a + 6]))
        lines.append("    -1")
    return "\r\n".join(lines) + "\r\n"


def test_testlab_style_file_identifies_without_edits(tmp_path):
    true_f = np.array([23.0, 47.5, 81.0, 122.0, 166.0])
    mm, _ = modal_system(true_f, np.full(5, 0.01), n_dof=9, rng=np.random.default_rng(4))
    freq = np.arange(1, 1601) * 0.125
    dofs = [str(d) for d in mm.dofs]
    H = mm.frf(freq, responses=dofs[1:], references=dofs[:1], quantity="accelerance").H[:, 0, :]
    responses = [(i + 2, 3 if i % 3 else -3) for i in range(H.shape[0])]
    # a -Z label carries the negated data, as exporters do for sensors mounted upside down
    Hs = np.array([h * (1 if d > 0 else -1) for h, (n, d) in zip(H, responses)])
    path = tmp_path / "testlab_export.unv"
    path.write_bytes(_testlab_ascii(freq, Hs, responses, ref=1).encode("ascii"))
    read = FRF.from_uff(path)
    assert read.shape == (8, 1, 1600) and read.quantity == "accelerance"
    modes, _ = identify(read)
    assert modes.n_modes == true_f.size
    np.testing.assert_allclose(np.sort(modes.freq_hz), true_f, rtol=1e-3)
    # and through the CLI
    assert main(["identify", str(path), "-o", str(tmp_path / "modes.uff")]) == 0
