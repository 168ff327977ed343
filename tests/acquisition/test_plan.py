"""Test-plan validation: every mistake gets a clear error naming the value."""
import copy

import pytest

from acquisition.plan import TestPlan, load_plan
from modalab.errors import PlanError
from modalab.units import G

BASE = {
    "acquisition": {"sample_rate_hz": 2048.0, "bandwidth_hz": 800.0, "record_s": 2.0, "pretrigger_s": 0.02,
                    "averages": 3, "max_hits": 5},
    "trigger": {"channel": "hammer", "level": 10.0},
    "channels": [
        {"name": "hammer", "physical": "ai0", "role": "force", "dof": "roving", "sensitivity": 2.25,
         "sensitivity_unit": "mV/N", "range": 500.0},
        {"name": "acc1", "physical": "ai1", "role": "response", "dof": "3+Z", "sensitivity": 100.0,
         "sensitivity_unit": "mV/g", "range": 500.0},
    ],
    "roving": {"pattern": "hammer", "points": ["1+Z", "2+Z", "3+Z"]},
}


def mod(**changes):
    d = copy.deepcopy(BASE)
    for path, value in changes.items():
        sec, key = path.split("__")
        if value is None:
            d[sec].pop(key)
        else:
            d[sec][key] = value
    return d


def test_valid_plan():
    p = TestPlan.from_dict(BASE)
    assert p.acq.n_samples == 4096 and p.acq.pretrigger_samples == 41
    assert p.channels[0].sensitivity == pytest.approx(2.25e-3)
    assert p.channels[1].sensitivity == pytest.approx(0.1 / G)
    cfg = p.channel_configs("2+Z")
    assert str(cfg[0].dof) == "2+Z" and str(cfg[1].dof) == "3+Z"
    assert p.roving_channel == "hammer"


@pytest.mark.parametrize("changes,match", [
    ({"acquisition__pretrigger_s": 3.0}, "pretrigger .* is not shorter than the record"),
    ({"acquisition__bandwidth_hz": 1000.0}, "2.56"),
    ({"acquisition__record_s": None}, "record_s or n_samples"),
    ({"acquisition__max_hits": 2}, "averages <= max_hits"),
    ({"trigger__channel": "nope"}, "trigger channel 'nope'"),
    ({"trigger__level": 900.0}, "trigger level 900"),
    ({"roving__points": ["1+Z", "1+W"]}, "1\\+W"),
    ({"roving__points": []}, "points is empty"),
    ({"roving__pattern": "laser"}, "roving pattern 'laser'"),
    ({"roving__points": ["1+Z", "1+Z"]}, "repeat"),
])
def test_invalid_plans(changes, match):
    with pytest.raises(PlanError, match=match):
        TestPlan.from_dict(mod(**changes))


def test_bad_channel_fields():
    d = copy.deepcopy(BASE)
    d["channels"][1]["sensitivity_unit"] = "pC/g"
    with pytest.raises(PlanError, match="pC/g"):
        TestPlan.from_dict(d)
    d = copy.deepcopy(BASE)
    d["channels"][1]["dof"] = "roving"
    with pytest.raises(PlanError, match="exactly one force channel"):
        TestPlan.from_dict(d)
    d = copy.deepcopy(BASE)
    del d["channels"][1]
    with pytest.raises(PlanError, match="no response channel"):
        TestPlan.from_dict(d)


def test_range_below_expected_force():
    d = copy.deepcopy(BASE)
    d["hammer"] = {"url": "simhammer://x", "force_n": 800.0}
    with pytest.raises(PlanError, match="exceeds the force channel range 500"):
        TestPlan.from_dict(d)


def test_unknown_dof_against_geometry():
    d = copy.deepcopy(BASE)
    d["geometry"] = {"1": [0, 0, 0], "2": [1, 0, 0]}
    with pytest.raises(PlanError, match="node 3"):
        TestPlan.from_dict(d)


def test_load_plan_errors(tmp_path):
    with pytest.raises(PlanError, match="cannot read"):
        load_plan(tmp_path / "missing.toml")
    (tmp_path / "bad.toml").write_text("[acquisition\n")
    with pytest.raises(PlanError, match="not valid TOML"):
        load_plan(tmp_path / "bad.toml")
    (tmp_path / "x.toml").write_text("[acquisitio]\nsample_rate_hz=1\n")
    with pytest.raises(PlanError, match="unknown section"):
        load_plan(tmp_path / "x.toml")
