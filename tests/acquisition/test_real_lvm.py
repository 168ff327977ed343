"""A real hammer hit (ladisk ImageBasedModalAnalysisTutorial, acceleration.lvm; see SOURCE.md there).

Two channels at 50 kHz: acceleration in g and force in N, LabVIEW text with a decimal comma.
SOURCE.md: the FRF peaks lie near 696, 1898 and 3672 Hz.
"""
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as ss

from acquisition.checks import check_hit
from acquisition.spectral import estimate_frf
from acquisition.windows import ExponentialWindow, ForceWindow
from modalab.core.lvm import LvmError, parse_lvm, read_lvm
from modalab.core.units import G

DATA = Path("/work/shared/data/real/ladisk-impact-hit/acceleration.lvm")
if not DATA.exists():  # the data may sit beside the checkout elsewhere
    DATA = Path(__file__).resolve().parents[3] / "shared/data/real/ladisk-impact-hit/acceleration.lvm"
pytestmark = pytest.mark.skipif(not DATA.exists(), reason="real .lvm data not available")


@pytest.fixture(scope="module")
def hit():
    return read_lvm(DATA, dofs=["2+Z", "1+Z"])


def test_reads_header_channels_and_units(hit):
    lf = parse_lvm(DATA)
    assert lf.header["Decimal_Separator"] == "," and lf.header["Operator"] == "Domen"
    seg = lf.segments[0]
    assert seg.names == ["Acceleration (Trigger)", "Force (Trigger)"]
    assert seg.unit_labels == ["g", "Newtons"] and seg.delta_x == [2e-5, 2e-5]
    assert seg.data.shape == (2, 50030)
    assert seg.data[:, 0] == pytest.approx([-0.007387, 0.232147])      # first data row, decimal comma
    assert hit.sample_rate_hz == pytest.approx(50000.0)
    assert hit.n_samples == 50030
    assert hit.roles == ["response", "force"] and hit.units == ["m/s^2", "N"]
    np.testing.assert_allclose(hit.data[0], seg.data[0] * G)           # g converted to m/s^2
    assert [str(d) for d in hit.dofs] == ["2+Z", "1+Z"]
    assert 20 <= hit.trigger_index <= 35                                # the pulse rises around sample 29
    assert hit.metadata["channel_names"][1] == "Force (Trigger)"


def test_frf_peaks_where_the_source_says(hit):
    frf = estimate_frf([hit], force_window=ForceWindow(length_s=0.002, taper_s=0.001),
                       exp_window=ExponentialWindow(end_level=0.01))
    assert frf.quantity == "accelerance" and frf.window_beta_per_s == pytest.approx(
        -np.log(0.01) / ((50030 - 1 - hit.trigger_index) * 2e-5))
    f, m = frf.freq_hz, np.abs(frf.H[0, 0])
    band = (f > 100) & (f < 5000)
    peaks, _ = ss.find_peaks(np.where(band, m, 0), prominence=5 * np.median(m[band]), distance=200)
    top = np.sort(f[peaks[np.argsort(m[peaks])[::-1][:3]]])
    np.testing.assert_allclose(top, [696.0, 1898.0, 3672.0], rtol=0.005)


def test_checks_pass_on_the_real_hit_and_flag_doctored_copies(hit):
    rep = check_hit(hit)
    assert rep.ok, rep.messages
    assert 150 < rep.peak_force < 250 and 1e-4 < rep.pulse_width_s < 5e-4
    # a second impact 5 ms later at half the force
    dbl = hit.copy()
    k = int(np.argmax(dbl.data[1]))
    lag = int(0.005 * hit.sample_rate_hz)
    dbl.data[1, k - 10 + lag:k + 10 + lag] += 0.5 * (hit.data[1, k - 10:k + 10] - np.median(hit.data[1, :20]))
    assert "double_hit" in check_hit(dbl).flags
    # the accelerometer channel clipped at +-20 g
    clip = hit.copy()
    clip.data[0] = np.clip(clip.data[0], -20 * G, 20 * G)
    assert check_hit(clip, ranges=[20 * G, 500.0]).overloaded_channels == (0,)
    assert check_hit(clip).overloaded_channels == (0,)                   # flat top without range info


LVM_HEAD = """LabVIEW Measurement\t
Writer_Version\t2
Reader_Version\t2
Separator\tTab
Decimal_Separator\t{dec}
Multi_Headings\tYes
X_Columns\t{xcols}
Time_Pref\tAbsolute
***End_of_Header***\t

Channels\t2\t\t
Samples\t4\t4\t
Y_Unit_Label\tN\tm/s^2\t
X_Dimension\tTime\tTime\t
X0\t0{d}0\t0{d}0\t
Delta_X\t1{d}0E-3\t1{d}0E-3\t
***End_of_Header***\t\t\t
"""


def write(tmp_path, text, name="x.lvm"):
    p = tmp_path / name
    p.write_text(text)
    return p


def small(dec=".", xcols="No"):
    head = LVM_HEAD.format(dec=dec, d=dec, xcols=xcols)
    if xcols == "Multi":
        head += "X_Value\tHammer\tX_Value\tAccel\tComment\n"
        rows = [f"{k}\t{v}\t{k}\t-{v}" for k, v in enumerate(["0", "5", "1", "0"])]
    else:
        head += "X_Value\tHammer\tAccel\tComment\n"
        rows = [("" if xcols == "No" else str(k)) + f"\t{v}\t{-float(v.replace(',', '.'))}".replace(".", dec)
                for k, v in enumerate(["0", "5", "1", "0"])]
    return head + "\n".join(rows) + "\n"


@pytest.mark.parametrize("dec, xcols", [(".", "No"), (",", "No"), (".", "One"), (".", "Multi")])
def test_small_files_in_every_layout(tmp_path, dec, xcols):
    rec = read_lvm(write(tmp_path, small(dec, xcols)), dofs=["1+Z", "1+Z"])
    assert rec.sample_rate_hz == pytest.approx(1000.0)
    assert rec.roles == ["force", "response"] and rec.units == ["N", "m/s^2"]
    np.testing.assert_allclose(rec.data, [[0, 5, 1, 0], [0, -5, -1, 0]])
    assert rec.trigger_index == 1


def test_comma_separated_file(tmp_path):
    text = small(".", "One").replace("\t", ",").replace("Separator,Tab", "Separator,Comma")
    rec = read_lvm(write(tmp_path, text))
    np.testing.assert_allclose(rec.data, [[0, 5, 1, 0], [0, -5, -1, 0]])
    assert parse_lvm(tmp_path / "x.lvm").header["Separator"] == "Comma"


def test_caller_overrides_roles_units_and_trigger(tmp_path):
    rec = read_lvm(write(tmp_path, small()), roles=["force", "response"], units=["kN", "g"], trigger_index=0,
                   hit_id=7)
    np.testing.assert_allclose(rec.data[0], [0, 5000, 1000, 0])
    np.testing.assert_allclose(rec.data[1], np.array([0, -5, -1, 0]) * G)
    assert rec.trigger_index == 0 and rec.hit_id == 7 and [str(d) for d in rec.dofs] == ["1", "2"]


@pytest.mark.parametrize("mutate, match", [
    (lambda s: "garbage\n" + s, "LabVIEW Measurement"),
    (lambda s: s.split("***End_of_Header***")[0], "End_of_Header"),
    (lambda s: s.rsplit("\n", 3)[0] + "\n", "declares 4 samples but holds 2"),
    (lambda s: s.replace("\t5\t", "\tfive\t"), "five"),
    (lambda s: s.replace("Channels\t2", "Channels\tzwei"), "Channels"),
    (lambda s: s.replace("Delta_X\t1.0E-3\t1.0E-3", "Delta_X\t1.0E-3\t"), "Delta_X"),
    (lambda s: s.replace("Y_Unit_Label\tN\tm/s^2", "Y_Unit_Label\tfurlong\tm/s^2"), "furlong"),
    (lambda s: s.replace("\t1\t-1.0", "\t1"), "fields"),
    (lambda s: s.replace("X_Value\tHammer", "Time\tHammer"), "X_Value"),
])
def test_malformed_files_raise_clear_errors(tmp_path, mutate, match):
    p = write(tmp_path, mutate(small()))
    with pytest.raises(LvmError, match=match) as ei:
        read_lvm(p)
    assert "x.lvm" in str(ei.value)
    assert isinstance(ei.value, ValueError)


def test_missing_file(tmp_path):
    with pytest.raises(LvmError, match="cannot read"):
        read_lvm(tmp_path / "nope.lvm")
