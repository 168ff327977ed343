"""The NI-DAQmx backend against the real package's signatures (create_autospec).

A misspelled method or keyword fails here because every nidaqmx object the
backend touches is an autospec of the real class.
"""
from unittest import mock

import numpy as np
import pytest

nidaqmx = pytest.importorskip("nidaqmx")
from nidaqmx.constants import AcquisitionType, Coupling, ExcitationSource, Slope  # noqa: E402
from nidaqmx.errors import DaqError as NiDaqError, DaqNotFoundError as NiNotFound  # noqa: E402
from nidaqmx.stream_readers import AnalogMultiChannelReader  # noqa: E402
from nidaqmx.task import Task  # noqa: E402
from nidaqmx.task._in_stream import InStream  # noqa: E402
from nidaqmx.task._timing import Timing  # noqa: E402
from nidaqmx.task.channels import AIChannel  # noqa: E402
from nidaqmx.task.collections import AIChannelCollection  # noqa: E402
from nidaqmx.task.triggering import Triggers  # noqa: E402
from nidaqmx.task.triggering._reference_trigger import ReferenceTrigger  # noqa: E402

from acquisition.nidaqmx_backend import NidaqmxBackend  # noqa: E402
from modalab.core.daqconfig import AcquisitionConfig, ChannelConfig  # noqa: E402
from modalab.core.errors import DaqError, DaqNotFoundError, DaqTimeoutError  # noqa: E402
from modalab.core.units import G  # noqa: E402

CHANNELS = [
    ChannelConfig("cDAQ1Mod1/ai0", "5+Z", "force", sensitivity=2.25e-3, range=500.0),
    ChannelConfig("cDAQ1Mod1/ai1", "1+Z", "response", sensitivity=10.2e-3 / G, range=200.0),
    ChannelConfig("cDAQ1Mod1/ai2", "2-Y", "response", sensitivity=9.9e-3 / G, range=200.0, iepe=False),
]
ACQ = AcquisitionConfig(sample_rate_hz=2048.0, n_samples=4096, pretrigger_samples=128, trigger_level=8.0)


def make_task(overloaded=()):
    task = mock.create_autospec(Task, instance=True)
    task.ai_channels = mock.create_autospec(AIChannelCollection, instance=True)
    task.ai_channels.add_ai_force_iepe_chan.return_value = mock.create_autospec(AIChannel, instance=True)
    task.ai_channels.add_ai_accel_chan.return_value = mock.create_autospec(AIChannel, instance=True)
    task.timing = mock.create_autospec(Timing, instance=True)
    task.triggers = mock.create_autospec(Triggers, instance=True)
    task.triggers.reference_trigger = mock.create_autospec(ReferenceTrigger, instance=True)
    task.in_stream = mock.create_autospec(InStream, instance=True)
    task.in_stream.overloaded_chans_exist = bool(overloaded)
    task.in_stream.overloaded_chans = list(overloaded)
    return task


@pytest.fixture
def reader_cls():
    with mock.patch("nidaqmx.stream_readers.AnalogMultiChannelReader", autospec=True) as cls:
        def fill(data, number_of_samples_per_channel, timeout):
            data[:] = np.arange(data.shape[0])[:, None] + 0.5
            return number_of_samples_per_channel
        cls.return_value.read_many_sample.side_effect = fill
        yield cls


def test_configure_translates_channels_timing_and_trigger(reader_cls):
    task = make_task()
    b = NidaqmxBackend(task_factory=lambda: task)
    b.configure(CHANNELS, ACQ)
    f = task.ai_channels.add_ai_force_iepe_chan.call_args
    assert f.args == ("cDAQ1Mod1/ai0",)
    assert f.kwargs["sensitivity"] == pytest.approx(2.25)        # mV/N
    assert f.kwargs["min_val"] == -500.0 and f.kwargs["max_val"] == 500.0
    assert f.kwargs["current_excit_source"] == ExcitationSource.INTERNAL
    calls = task.ai_channels.add_ai_accel_chan.call_args_list
    assert [c.args[0] for c in calls] == ["cDAQ1Mod1/ai1", "cDAQ1Mod1/ai2"]
    assert calls[0].kwargs["sensitivity"] == pytest.approx(10.2)  # mV/g
    assert calls[1].kwargs["current_excit_source"] == ExcitationSource.NONE
    assert task.ai_channels.add_ai_accel_chan.return_value.ai_coupling == Coupling.DC  # last one set: DC
    task.timing.cfg_samp_clk_timing.assert_called_once_with(2048.0, sample_mode=AcquisitionType.FINITE,
                                                           samps_per_chan=4096)
    task.triggers.reference_trigger.cfg_anlg_edge_ref_trig.assert_called_once_with(
        "cDAQ1Mod1/ai0", pretrigger_samples=128, trigger_slope=Slope.RISING, trigger_level=8.0)
    reader_cls.assert_called_once_with(task.in_stream)


def test_record_labels_and_overload_flags(reader_cls):
    task = make_task(overloaded=["cDAQ1Mod1/ai1"])
    with NidaqmxBackend(task_factory=lambda: task) as b:
        b.configure(CHANNELS, ACQ)
        b.arm()
        task.start.assert_called_once_with()
        rec = b.wait()
    assert rec.data.shape == (3, 4096)
    assert rec.trigger_index == 128
    assert [str(d) for d in rec.dofs] == ["5+Z", "1+Z", "2-Y"]
    assert rec.roles == ["force", "response", "response"]
    assert list(rec.overload) == [False, True, False]
    task.close.assert_called_once_with()


def test_timeout_means_no_hit_yet(reader_cls):
    task = make_task()
    reader_cls.return_value.read_many_sample.side_effect = NiDaqError("Some or all of the samples requested have not yet been acquired.", -200284)
    b = NidaqmxBackend(task_factory=lambda: task)
    b.configure(CHANNELS, ACQ)
    b.arm()
    with pytest.raises(DaqTimeoutError, match="no hit"):
        b.wait(timeout_s=0.1)


def test_other_driver_errors_become_daq_errors(reader_cls):
    task = make_task()
    task.timing.cfg_samp_clk_timing.side_effect = NiDaqError("Requested sample rate is too high", -200332)
    b = NidaqmxBackend(task_factory=lambda: task)
    with pytest.raises(DaqError, match="-200332.*NI MAX"):
        b.configure(CHANNELS, ACQ)


def test_missing_driver_is_a_clear_message_not_a_daq_error():
    def no_driver():
        raise NiNotFound("Could not find an installation of NI-DAQmx.")
    b = NidaqmxBackend(task_factory=no_driver)
    with pytest.raises(DaqNotFoundError, match="--backend sim") as ei:
        b.configure(CHANNELS, ACQ)
    assert not isinstance(ei.value, DaqError)


def test_real_package_without_driver_gives_clear_message():
    # On machines without NI-DAQmx (CI), the real Task() raises the driver error.
    b = NidaqmxBackend()
    try:
        b.configure(CHANNELS, ACQ)
    except DaqNotFoundError as e:
        assert "Install NI-DAQmx" in str(e)
    else:  # pragma: no cover - a machine with the driver (and perhaps no device)
        b.close()


def test_typo_in_api_would_fail():
    # the autospec rejects unknown keywords: prove the guard works
    task = make_task()
    with pytest.raises(TypeError):
        task.ai_channels.add_ai_accel_chan("x", sensitivty=1.0)


def test_the_ac_coupling_corner_is_recorded_with_every_hit(reader_cls, tmp_path):
    """The plan's corner of each AC-coupled (IEPE) input goes into every hit's metadata, 0 for the DC-coupled
    channel, and survives the UFF (ID line 4): the FRF step keeps the coupling's undershoot with the force."""
    from modalab.core import uff

    chans = [ChannelConfig(c.physical, c.dof, c.role, c.sensitivity, c.range, iepe=c.iepe,
                           highpass_hz=hp if c.iepe else None) for c, hp in zip(CHANNELS, (0.35, 1.6, None))]
    task = make_task()
    with NidaqmxBackend(task_factory=lambda: task) as b:
        b.configure(chans, ACQ)
        f_chan = task.ai_channels.add_ai_force_iepe_chan.return_value
        assert f_chan.ai_coupling == Coupling.AC
        b.arm()
        rec = b.wait()
    assert rec.metadata["highpass_hz"] == [0.35, 1.6, 0.0]
    assert rec.highpass_hz() == [0.35, 1.6, 0.0]
    uff.write_records(tmp_path / "hit.uff", [rec])
    assert uff.read_records(tmp_path / "hit.uff")[0].highpass_hz() == pytest.approx([0.35, 1.6, 0.0])


def test_an_ac_coupled_channel_without_its_corner_records_none_and_says_so(reader_cls, caplog):
    """NI-DAQmx has no attribute for the coupling's corner: without the plan's value nothing is guessed."""
    task = make_task()
    with caplog.at_level("WARNING", logger="acquisition.nidaqmx_backend"):
        with NidaqmxBackend(task_factory=lambda: task) as b:
            b.configure(CHANNELS, ACQ)                 # IEPE channels ai0 and ai1 without highpass_hz
            b.arm()
            rec = b.wait()
    assert "highpass_hz" not in rec.metadata and rec.highpass_hz() is None
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and "cDAQ1Mod1/ai0, cDAQ1Mod1/ai1" in said[0] and "cDAQ1Mod1/ai2" not in said[0]
    assert "highpass_hz" in said[0] and "specifications" in said[0], said
