"""Serial instruments: protocol transcripts over pyserial URL handlers.

The drivers talk to the simulated twins through ``serial.serial_for_url``
(``simcond://`` and ``simhammer://``), and to ``loop://`` for transport tests;
each test checks the exact command/reply transcript.
"""
import pytest

from acquisition.instruments import AutoHammer, IEPEConditioner, LineTransport
from hardware_sim import serial_devices as sd
from modalab.core.errors import ModalabValueError, SerialProtocolError


@pytest.fixture(autouse=True)
def fresh():
    sd.register()
    sd.reset_devices()
    yield
    sd.reset_devices()


def expected_protocol(dev, transcript):
    assert dev.log == transcript


class TestConditioner:
    def test_setup_iepe_transcript(self):
        cond = IEPEConditioner(LineTransport.from_url("simcond://bench", timeout=0.5), unit=1)
        cond.setup_iepe(3, gain=10)
        expected_protocol(sd.device("simcond://bench"), [
            ("1:3:MODE=IEPE", "1:3:MODE=IEPE"), ("1:3:EXC=ON", "1:3:EXC=ON"),
            ("1:3:GAIN=10", "1:3:GAIN=10"), ("1:3:STAT?", "1:3:STAT=OK")])

    def test_overload_latch_is_read_and_cleared(self):
        cond = IEPEConditioner(LineTransport.from_url("simcond://b2", timeout=0.5))
        sd.device("simcond://b2").ovl[2] = True
        assert cond.status(2) == "OVL"
        assert cond.overload(2) is True
        assert cond.overload(2) is False

    def test_open_sensor_is_reported_with_advice(self):
        cond = IEPEConditioner(LineTransport.from_url("simcond://b3", timeout=0.5))
        sd.device("simcond://b3").fault[5] = "OPEN"
        with pytest.raises(SerialProtocolError, match="OPEN.*cable"):
            cond.setup_iepe(5)

    def test_device_error_reply_raises(self):
        cond = IEPEConditioner(LineTransport.from_url("simcond://b4", timeout=0.5), unit=2)
        with pytest.raises(SerialProtocolError, match="no such channel"):
            cond.gain(1)

    def test_bad_arguments_never_reach_the_wire(self):
        cond = IEPEConditioner(LineTransport.from_url("simcond://b5", timeout=0.5))
        with pytest.raises(ModalabValueError, match="gain 7"):
            cond.set_gain(1, 7)
        with pytest.raises(ModalabValueError, match="channel 9"):
            cond.set_gain(9, 1)
        assert sd.device("simcond://b5").log == []

    def test_garbled_reply_over_loop(self):
        # loop:// echoes what we send: the driver must see it is not a valid reply
        cond = IEPEConditioner(LineTransport.from_url("loop://", timeout=0.2))
        with pytest.raises(SerialProtocolError, match="expected '1:1:GAIN=VALUE'"):
            cond.gain(1)

    def test_silent_device_times_out_clearly(self):
        t = LineTransport.from_url("loop://", timeout=0.05)
        with pytest.raises(SerialProtocolError, match="no complete reply"):
            t.read_line()


class TestAutoHammer:
    def test_arm_fire_transcript_and_callback(self):
        fired = []
        dev = sd.device("simhammer://h1")
        dev.on_fire = fired.append
        h = AutoHammer(LineTransport.from_url("simhammer://h1", timeout=0.5))
        h.arm()
        h.fire(120.0)
        assert fired == [120.0]
        assert h.status() == "READY"
        expected_protocol(dev, [("ARM", "OK"), ("LEVEL?", "LEVEL 5 800"), ("FIRE 120", "OK"), ("STAT?", "READY")])

    def test_fire_without_arm_is_refused(self):
        h = AutoHammer(LineTransport.from_url("simhammer://h2", timeout=0.5))
        with pytest.raises(SerialProtocolError, match="not armed"):
            h.fire(50.0)

    def test_force_outside_range(self):
        h = AutoHammer(LineTransport.from_url("simhammer://h3", timeout=0.5))
        h.arm()
        with pytest.raises(ModalabValueError, match="5..800 N"):
            h.fire(2000.0)

    def test_fault_state(self):
        dev = sd.device("simhammer://h4")
        dev.fault = "tip jammed"
        h = AutoHammer(LineTransport.from_url("simhammer://h4", timeout=0.5))
        assert h.status() == "FAULT tip jammed"
        with pytest.raises(SerialProtocolError, match="tip jammed"):
            h.arm()

    def test_unknown_port_is_clear(self):
        with pytest.raises(SerialProtocolError, match="cannot open serial port"):
            LineTransport.from_url("/dev/does-not-exist-modalab")
