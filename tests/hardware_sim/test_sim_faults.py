"""Every injectable fault happens when asked, and shows in the record or as the right exception."""
import numpy as np
import pytest
from dataclasses import replace

from hardware_sim import ChannelSetup, FaultConfig, Hammer, SimulatedLab, demo_channels, demo_lab, demo_setup
from hardware_sim.demo import demo_structure
from modalab.core.errors import DaqError, DaqTimeoutError, DeviceLostError, ModalabValueError


def pulses_in(force, frac=0.1):
    """Separate excursions above ``frac`` of the peak, in samples (start indices)."""
    above = force > frac * force.max()
    return np.flatnonzero(above[1:] & ~above[:-1]) + 1


class TestTrigger:
    def test_trigger_never_comes_on_the_scheduled_arm(self):
        lab = demo_lab(1, faults=FaultConfig(no_trigger_on=(2,)))
        assert lab.hit("4+Z").hit_id == 1
        lab.arm()
        for _ in range(2):                               # waiting again does not help
            with pytest.raises(DaqTimeoutError, match="trigger never comes"):
                lab.wait(timeout_s=1.0)
        lab.abort()
        assert lab.hit().hit_id == 2                     # arm 3 is healthy
        assert lab.n_armed == 3

    def test_timeout_is_a_daq_error_and_a_timeout(self):
        lab = demo_lab(1, faults=FaultConfig(no_trigger_probability=1.0))
        lab.arm()
        with pytest.raises(TimeoutError):
            lab.wait()
        with pytest.raises(DaqError):
            lab.wait()


class TestDeviceLost:
    def test_device_disappears_mid_record_until_reconnected(self):
        waited = []
        lab = demo_lab(2, faults=FaultConfig(device_lost_on=(2,)), sleep=waited.append)
        lab.hit("4+Z")
        lab.arm()
        with pytest.raises(DeviceLostError, match="disappeared .* into the record"):
            lab.wait()
        assert 0 < waited[-1] < lab.setup.duration_s      # it died during the record
        assert lab.state == "lost"
        with pytest.raises(DeviceLostError, match="reconnect"):
            lab.arm()
        lab.reconnect()
        r = lab.hit()
        assert r.hit_id == 2 and not r.overloaded


class TestOverloadStorm:
    def test_scheduled_storm_overloads_every_channel_of_that_hit_only(self):
        lab = demo_lab(3, faults=FaultConfig(overload_storm_on=(2,)))
        recs = [lab.hit("4+Z") for _ in range(3)]
        assert [r.overload.all() for r in recs] == [False, True, False]
        assert [r.overloaded for r in recs] == [False, True, False]
        assert recs[1].metadata["sim"]["overload_storm"]
        # the transients clip at the ADC range
        for c in range(recs[1].n_channels):
            assert np.abs(recs[1].data[c]).max() >= 0.999 * recs[1].metadata["range"][c]

    def test_probabilistic_storm_lasts_its_length(self):
        lab = demo_lab(4, faults=FaultConfig(overload_storm_probability=1.0, overload_storm_length=2))
        assert all(lab.hit("4+Z").overload.all() for _ in range(3))


class TestDoubleHit:
    def test_scheduled_double_hit_has_two_pulses(self):
        lab = demo_lab(5, hammer=Hammer(double_hit_delay_s=(0.01, 0.02)), faults=FaultConfig(double_hit_on=(1,)))
        r = lab.hit("11+Z")
        sim = r.metadata["sim"]
        assert sim["double_hit"] and len(sim["pulse_starts_s"]) == 2
        starts = pulses_in(r.force[0])
        assert len(starts) == 2
        gap = (starts[1] - starts[0]) * r.dt
        assert gap == pytest.approx(sim["pulse_starts_s"][1] - sim["pulse_starts_s"][0], abs=2 * r.dt)
        assert 0.1 <= sim["pulse_peaks_n"][1] / sim["pulse_peaks_n"][0] <= 0.5
        r2 = lab.hit()
        assert not r2.metadata["sim"]["double_hit"] and len(pulses_in(r2.force[0])) == 1

    def test_hammer_rebound_probability(self):
        lab = demo_lab(6, hammer=Hammer(double_hit_probability=0.5))
        doubles = [lab.hit("4+Z").metadata["sim"]["double_hit"] for _ in range(16)]
        assert 2 <= sum(doubles) <= 14

    def test_automatic_hammer_does_not_rebound_unless_injected(self):
        lab = demo_lab(7, hammer=Hammer(automatic=True, double_hit_probability=1.0))
        assert not lab.hit("4+Z", force_n=100).metadata["sim"]["double_hit"]
        lab = demo_lab(7, hammer=Hammer(automatic=True), faults=FaultConfig(double_hit_on=(1,)))
        assert lab.hit("4+Z", force_n=100).metadata["sim"]["double_hit"]


class TestChannelFaults:
    def test_dead_accelerometer_reads_only_converter_noise(self):
        ch = demo_channels()
        ch[2] = replace(ch[2], dead=True)
        setup = demo_setup()
        r = SimulatedLab(demo_structure(), ch, setup, rng=8).hit("4+Z")
        dead = r.data[2] * r.sensitivity[2]
        assert np.std(dead) == pytest.approx(setup.adc_noise_v_rms, rel=0.1)
        assert np.abs(r.data[2]).max() < 1e-3 * np.abs(r.data[1]).max()
        assert r.metadata["sim"]["dead_channels"] == [2]

    def test_noisy_channel_is_noisier(self):
        ch = demo_channels()
        ch[1] = replace(ch[1], extra_noise_v_rms=2e-3)
        r = SimulatedLab(demo_structure(), ch, demo_setup(pretrigger_samples=1024), rng=9).hit("4+Z")
        # volts well before the hit (the zero-phase anti-alias filter rings a few dozen samples ahead of it)
        pre = r.data[:, : r.trigger_index - 100] * r.sensitivity[:, None]
        assert np.std(pre[1]) == pytest.approx(2e-3, rel=0.2)
        assert np.std(pre[1]) > 50 * np.std(pre[2])
        assert np.std(pre[2]) == pytest.approx(np.hypot(1e-5, 1e-6), rel=0.1)


class TestFaultConfig:
    def test_bad_values_are_explained(self):
        with pytest.raises(ModalabValueError, match="double_hit_probability=1.5"):
            FaultConfig(double_hit_probability=1.5)
        with pytest.raises(ModalabValueError, match="arm numbers start at 1"):
            FaultConfig(no_trigger_on=(0,))
        with pytest.raises(ModalabValueError, match="extra|noise"):
            ChannelSetup("1+Z", "response", 1.0, extra_noise_v_rms=-1.0)
