"""Per-hit quality checks on synthetic hits whose faults are known."""
import numpy as np
import pytest

from acquisition.checks import FLAGS, HitCheckConfig, HitReport, check_hit, check_hits
from modalab.core.errors import ModalabValueError
from modalab.core.records import TimeRecord

FS, N, TI = 10000.0, 8192, 200


def pulse(t, t0, amp, width):
    u = (t - t0) / width
    return np.where((u >= 0) & (u <= 1), amp * np.sin(np.pi * np.clip(u, 0, 1)), 0.0)


def make_hit(*, amp=100.0, width=6e-4, second=None, sigma=30.0, f0=120.0, noise=1e-3, pre_force=None,
             pre_resp=0.0, clip=None, overload=None, metadata=None, seed=0, ti=TI):
    """Force: half-sine at the trigger (+ optional second pulse (delay_s, rel_amp)); response: decaying sine."""
    rng = np.random.default_rng(seed)
    t = (np.arange(N) - ti) / FS
    f = pulse(t, 0.0, amp, width)
    if second is not None:
        f = f + pulse(t, second[0], second[1] * amp, width)
    if pre_force is not None:
        f = f + pulse(t, pre_force[0], pre_force[1] * amp, width)
    y = np.where(t >= 0, 0.05 * amp * np.exp(-sigma * np.clip(t, 0, None)) * np.sin(2 * np.pi * f0 * t), 0.0)
    y = y + pre_resp * 0.05 * amp * np.sin(2 * np.pi * f0 * t) * (t < 0)
    data = np.array([f, y])
    data += noise * np.abs(data).max(1, keepdims=True) * rng.standard_normal(data.shape)
    if clip is not None:
        data[1] = np.clip(data[1], -clip, clip)
    return TimeRecord(sample_rate_hz=FS, data=data, dofs=["1+Z", "2+Z"], roles=["force", "response"],
                      trigger_index=ti, overload=overload, metadata=metadata or {}, hit_id=seed + 1)


def test_clean_hit_passes():
    rep = check_hit(make_hit())
    assert isinstance(rep, HitReport)
    assert rep.ok, rep.messages
    assert rep.peak_force == pytest.approx(100.0, rel=0.01)
    assert rep.pulse_width_s == pytest.approx(6e-4, abs=2 / FS)
    assert rep.spectral_dip_db < 1.0 and rep.double_hit_ratio < 0.05
    assert rep.summary().startswith("hit 1: ok")


@pytest.mark.parametrize("delay, ratio", [(3e-3, 0.4), (0.02, 0.2)])
def test_double_hit_in_time_and_spectrum(delay, ratio):
    rep = check_hit(make_hit(second=(delay, ratio)))
    assert "double_hit" in rep.flags
    assert rep.double_hit_ratio == pytest.approx(ratio, abs=0.02)
    assert rep.double_hit_delay_s == pytest.approx(delay, abs=3 / FS)
    if delay < 0.01:
        assert "double_hit_spectral" in rep.flags and rep.spectral_dip_db > 6


def test_small_rebound_is_below_threshold():
    rep = check_hit(make_hit(second=(3e-3, 0.05)))
    assert "double_hit" not in rep.flags
    assert check_hit(make_hit(second=(3e-3, 0.05)), HitCheckConfig(double_hit_level=0.03, dip_db=20)).flags == \
        ("double_hit",)


def test_spectral_heuristic_on_its_own():
    # with the time-domain check made blind, the notches of a double hit still show in the force spectrum
    cfg = HitCheckConfig(double_hit_level=0.99)
    rep = check_hit(make_hit(second=(2e-3, 0.5)), cfg)
    assert rep.flags == ("double_hit_spectral",)
    assert check_hit(make_hit(), cfg).ok


def test_overload_from_range_flat_top_and_device_flag():
    clipped = make_hit(clip=3.0)
    rep = check_hit(clipped, ranges=[500.0, 3.0])
    assert "overload" in rep.flags and rep.overloaded_channels == (1,)
    rep = check_hit(make_hit(clip=3.0, metadata={"range": [500.0, (-3.0, 3.0)]}))
    assert rep.overloaded_channels == (1,)
    assert check_hit(clipped).overloaded_channels == (1,)                  # no range: flat top at the extreme
    assert check_hit(make_hit(), ranges=[500.0, 10.0]).ok                   # well inside the range
    rep = check_hit(make_hit(overload=[True, False]))
    assert rep.overloaded_channels == (0,) and "device" in rep.messages[0]
    with pytest.raises(ModalabValueError, match="ranges"):
        check_hit(make_hit(), ranges=[1.0, 2.0, 3.0])


def test_weak_and_missing_trigger():
    rep = check_hit(make_hit(amp=0.5))
    assert rep.flags == ("weak_trigger",)
    assert check_hit(make_hit(amp=20.0)).ok
    rep = check_hit(make_hit(amp=20.0), trigger_level=25.0)          # below the DAQ's trigger threshold
    assert rep.flags == ("weak_trigger",) and "25 N" in rep.messages[0]
    rec = make_hit(amp=0.0, noise=0.0)
    rec.data[0] = np.random.default_rng(1).standard_normal(N) * 0.01
    rec.data[1] = np.random.default_rng(2).standard_normal(N) * 0.01
    rep = check_hit(rec)
    assert "missing_trigger" in rep.flags and "double_hit" not in rep.flags
    only_resp = TimeRecord(sample_rate_hz=FS, data=make_hit().data[1:], dofs=["2+Z"], roles=["response"])
    assert "missing_trigger" in check_hit(only_resp).flags


def test_not_decayed():
    rep = check_hit(make_hit(sigma=1.0))
    assert rep.flags == ("not_decayed",)
    assert rep.end_ratio[0] > 0.01
    assert check_hit(make_hit(sigma=1.0), HitCheckConfig(max_end_ratio=0.9)).ok


def test_pretrigger_content():
    rep = check_hit(make_hit(pre_force=(-0.015, 0.3)))
    assert "pretrigger_force" in rep.flags and rep.pretrigger_force_ratio == pytest.approx(0.3, abs=0.02)
    rep = check_hit(make_hit(pre_resp=0.5))
    assert rep.flags == ("pretrigger_response",)


def test_pulse_rising_before_the_trigger_is_not_pretrigger_content():
    rec = make_hit()
    rec.trigger_index = TI + 2                     # trigger level crossed two samples into the pulse
    assert check_hit(rec).ok


def test_config_validation_and_batch():
    with pytest.raises(ModalabValueError, match="double_hit_level"):
        HitCheckConfig(double_hit_level=1.5)
    with pytest.raises(ModalabValueError, match="rail_samples"):
        HitCheckConfig(rail_samples=0)
    with pytest.raises(ModalabValueError, match="TimeRecord"):
        check_hit(np.zeros((2, 10)))
    reps = check_hits([make_hit(seed=0), make_hit(seed=1, second=(3e-3, 0.5))])
    assert [r.ok for r in reps] == [True, False]
    assert set(reps[1].flags) <= set(FLAGS)


def test_flags_the_simulated_labs_double_hits_and_only_those():
    # hardware_sim: 2048 Hz, 24-bit ADC with a linear-phase anti-alias filter that rings around the
    # sub-millisecond pulse; the lab records the truth in metadata['sim'].
    import dataclasses

    from hardware_sim import demo_lab
    from hardware_sim.demo import DEMO_HAMMER

    lab = demo_lab(rng=5, hammer=dataclasses.replace(DEMO_HAMMER, double_hit_probability=0.5))
    n_double = 0
    for _ in range(12):
        rec = lab.hit("14+Z", force_n=150.0)
        truth = rec.metadata["sim"]
        rep = check_hit(rec, trigger_level=5.0)
        if truth["double_hit"]:
            ratio = truth["pulse_peaks_n"][1] / truth["pulse_peaks_n"][0]
            if ratio > 0.15:
                n_double += 1
                assert "double_hit" in rep.flags, (truth, rep)
        else:
            assert rep.ok, (truth, rep.messages)
    assert n_double >= 2
