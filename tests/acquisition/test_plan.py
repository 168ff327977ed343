"""Test-plan validation: every mistake gets a clear error naming the value."""
import copy

import pytest

from acquisition.plan import TestPlan, load_plan
from modalab.core.errors import PlanError
from modalab.core.units import G

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
    ({"acquisition__bandwidth_hz": 1000.0}, "2.56 .*: raise sample_rate_hz or lower bandwidth_hz$"),
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


# ------------------------------------------------------------------ the unit agrees with the role (a fresh user's bug)
def test_a_hammer_in_mv_per_g_is_an_error_naming_the_file_the_channel_and_the_units_expected():
    # a force channel with sensitivity_unit = "mV/g" was accepted: its volts read as N through an acceleration
    # sensitivity, and a simulated session ran to completion as if nothing were wrong
    d = copy.deepcopy(BASE)
    d["channels"][0]["sensitivity_unit"] = "mV/g"
    with pytest.raises(PlanError) as e:
        TestPlan.from_dict(d, source="my_plan.toml")
    msg = str(e.value)
    assert msg.startswith("my_plan.toml: channel 1 (hammer): sensitivity_unit = 'mV/g' is a sensitivity to "
                          "acceleration, but role = 'force' measures force; expected one of mV/N, V/N")
    assert "role = 'response'" in msg and "\n" not in msg


@pytest.mark.parametrize("unit", ["mV/N", "V/N", "v / n"])
def test_an_accelerometer_in_force_units_is_an_error(unit):
    d = copy.deepcopy(BASE)
    d["channels"][1]["sensitivity_unit"] = unit
    with pytest.raises(PlanError, match=rf"^p\.toml: channel 2 \(acc1\): sensitivity_unit = '{unit}' is a "
                                        r"sensitivity to force, but role = 'response' measures acceleration; "
                                        r"expected one of mV/g, V/g, mV/\(m/s\^2\), V/\(m/s\^2\)"):
        TestPlan.from_dict(d, source="p.toml")


@pytest.mark.parametrize("channel,unit,si", [
    (0, "V/N", 2.25), (0, "mV/N", 2.25e-3),
    (1, "V/g", 100.0 / G), (1, "mV/(m/s^2)", 0.1), (1, "V/(m/s^2)", 100.0), (1, "mV/m/s^2", 0.1),
])
def test_every_unit_of_the_roles_quantity_is_accepted(channel, unit, si):
    d = copy.deepcopy(BASE)
    d["channels"][channel]["sensitivity_unit"] = unit
    assert TestPlan.from_dict(d).channels[channel].sensitivity == pytest.approx(si)


def test_an_unknown_unit_is_still_named_before_the_role_is_checked():
    d = copy.deepcopy(BASE)
    d["channels"][0]["sensitivity_unit"] = "mV/xyz"
    with pytest.raises(PlanError, match=r"^p\.toml: channel 1 \(hammer\): sensitivity unit 'mV/xyz' unknown; "
                                        r"expected one of mV/N, V/N, mV/g"):
        TestPlan.from_dict(d, source="p.toml")


def test_the_inputs_ac_coupling_corner_reaches_the_channel_configs():
    """``highpass_hz``: the input's AC-coupling corner from the module's specifications, per channel; not stated
    is None (never a default number); negative, or on a DC-coupled channel, is an error naming the channel."""
    d = copy.deepcopy(BASE)
    d["channels"][0]["highpass_hz"] = 0.35
    cfg = TestPlan.from_dict(d).channel_configs("2+Z")
    assert cfg[0].highpass_hz == 0.35 and cfg[1].highpass_hz is None
    d["channels"][1].update(highpass_hz=-1.0)
    with pytest.raises(PlanError, match=r"channel 2 \(acc1\): highpass_hz -1"):
        TestPlan.from_dict(d)
    d["channels"][1].update(highpass_hz=1.6, iepe=False)
    with pytest.raises(PlanError, match="iepe = false"):
        TestPlan.from_dict(d)
    d["channels"][1]["highpass_hz"] = "1.6"
    with pytest.raises(PlanError, match="highpass_hz = '1.6' is not a valid number"):
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


# ------------------------------------------------------------------ typos and wrong types (issue 14 #7)
@pytest.mark.parametrize("section,typo,meant", [
    ("acquisition", "sample_rte_hz", "sample_rate_hz"),
    ("acquisition", "averges", "averages"),
    ("trigger", "slop", "slope"),
    ("windows", "exp_end_lvl", "exp_end_level"),
    ("roving", "pointz", "points"),
    ("hammer", "forc_n", "force_n"),
    ("sim", "hammer_mas_kg", "hammer_mass_kg"),
])
def test_misspelt_key_names_file_section_key_and_the_closest_key(section, typo, meant):
    d = copy.deepcopy(BASE)
    d.setdefault(section, {})[typo] = 1.0
    if section == "hammer":
        d["hammer"]["url"] = "simhammer://x"
    with pytest.raises(PlanError) as e:
        TestPlan.from_dict(d, source="my_plan.toml")
    assert str(e.value) == f"my_plan.toml: unknown key {section}.{typo}; did you mean {section}.{meant}?"


def test_misspelt_channel_key_and_section():
    d = copy.deepcopy(BASE)
    d["channels"][1]["sensitivty"] = 100.0
    with pytest.raises(PlanError, match=r"^p\.toml: unknown key channels\[2\]\.sensitivty; did you mean "
                                        r"channels\.sensitivity\?$"):
        TestPlan.from_dict(d, source="p.toml")
    d = copy.deepcopy(BASE)
    d["trigger_"] = {}
    with pytest.raises(PlanError, match=r"unknown section \[trigger_\]; did you mean trigger\?"):
        TestPlan.from_dict(d, source="p.toml")
    d = copy.deepcopy(BASE)
    d["acquisition"]["zzz"] = 1
    with pytest.raises(PlanError, match=r"unknown key acquisition\.zzz; valid keys: averages, bandwidth_hz"):
        TestPlan.from_dict(d, source="p.toml")


@pytest.mark.parametrize("changes,match", [
    ({"acquisition__averages": "three"}, r"acquisition\.averages = 'three' is not a valid whole number"),
    ({"acquisition__averages": 2.5}, r"acquisition\.averages = 2\.5 is not a valid whole number"),
    ({"acquisition__sample_rate_hz": "2048"}, r"acquisition\.sample_rate_hz = '2048' is not a valid number"),
    ({"trigger__level": True}, r"trigger\.level = True is not a valid number"),
    ({"trigger__slope": "up"}, r"trigger\.slope = 'up'; expected 'rising' or 'falling'"),
    ({"trigger__channel": 1}, r"trigger\.channel = 1 is not a valid string"),
    ({"acquisition__timeout_s": 0}, r"timeout_s = 0\.0 must be positive"),
])
def test_wrong_types_are_errors_not_coerced(changes, match):
    with pytest.raises(PlanError, match=match):
        TestPlan.from_dict(mod(**changes))


def test_a_section_that_is_not_a_table():
    d = copy.deepcopy(BASE)
    d["windows"] = 3
    with pytest.raises(PlanError, match=r"\[windows\] must be a table"):
        TestPlan.from_dict(d)


# ------------------------------------------------------------------ the one exponential-window rule (issue 15)
@pytest.mark.parametrize("windows,beta,end", [
    ({}, None, None), ({"exp_end_level": 0.0}, None, None), ({"exp_beta": 0.0}, None, None),
    ({"exp_end_level": 0.01}, None, 0.01), ({"exp_beta": 2.5}, 2.5, None),
])
def test_exp_window_rule(windows, beta, end):
    d = copy.deepcopy(BASE)
    d["windows"] = windows
    ew = TestPlan.from_dict(d).exp_window()
    if beta is None and end is None:
        assert ew is None
    else:
        assert ew.beta == beta and ew.end_level == end


def test_exp_window_both_or_invalid_is_an_error():
    for w, match in (({"exp_beta": 2.0, "exp_end_level": 0.01}, "both given; keep one"),
                     ({"exp_beta": -1.0}, "exp_beta = -1.0 must be a decay rate >= 0"),
                     ({"exp_end_level": 1.0}, r"exp_end_level = 1.0 must be in \[0, 1\)")):
        d = copy.deepcopy(BASE)
        d["windows"] = w
        with pytest.raises(PlanError, match=match):
            TestPlan.from_dict(d, source="p.toml")


@pytest.mark.parametrize("beta", [0.0, 3.0])
def test_session_and_modalab_frf_window_the_same_hits_alike(tmp_path, beta):
    # one rule (exponential_window) for a plan's exp_beta and `modalab frf --exp-beta`; exp_beta = 0 used to
    # build a beta-0 window in the session and none in `modalab frf` (the frf stage)
    import numpy as np

    from acquisition.session import frf_from_hits
    from hardware_sim import demo_lab
    from modalab.core import uff
    from modalab.app.stages import FRFOptions, frf

    lab = demo_lab(rng=1)
    recs = [lab.hit("14+Z", force_n=150.0) for _ in range(3)]
    for k, r in enumerate(recs, start=1):
        r.hit_id = k
    uff.write_records(tmp_path / "hits.uff", recs)
    d = copy.deepcopy(BASE)
    d["windows"] = {"exp_beta": beta, "force_fraction": 0.05, "force_taper": 0.0}
    plan = TestPlan.from_dict(d)
    a = frf_from_hits(recs, plan)
    b = frf(tmp_path / "hits.uff", tmp_path / "frf.uff",
            FRFOptions(exp_beta=beta, reciprocity=False, bandwidth_hz=plan.bandwidth_hz)).result
    assert a.H.shape == b.H.shape
    np.testing.assert_allclose(b.H, a.H, rtol=1e-6, atol=1e-9 * np.abs(a.H).max())
    assert a.window_beta_per_s == b.window_beta_per_s


# ------------------------------------------------------------------ files (issue 14 #11 and the tracebacks)
def test_relative_sim_structure_is_read_from_the_plans_folder(tmp_path, monkeypatch):
    import tomli_w

    (tmp_path / "plans").mkdir()
    (tmp_path / "plans" / "frame.bdf").write_text("$ empty\n")
    d = copy.deepcopy(BASE)
    d["sim"] = {"structure": "frame.bdf"}
    f = tmp_path / "plans" / "p.toml"
    f.write_text(tomli_w.dumps(d))
    monkeypatch.chdir(tmp_path)                  # not the plan's folder
    assert load_plan(f).sim["structure"] == str(tmp_path / "plans" / "frame.bdf")
    assert load_plan("plans/p.toml").sim["structure"] == str(tmp_path / "plans" / "frame.bdf")
    d["sim"] = {"structure": "missing.bdf"}
    f.write_text(tomli_w.dumps(d))
    with pytest.raises(PlanError, match=r"p\.toml: sim\.structure = 'missing\.bdf': no such file .*plans/missing\.bdf"):
        load_plan(f)


def test_binary_or_directory_plan_is_a_clear_error(tmp_path):
    f = tmp_path / "plan.toml"
    f.write_bytes(bytes(range(256)))
    with pytest.raises(PlanError, match=r"plan\.toml' is not a text file"):
        load_plan(f)
    with pytest.raises(PlanError, match="is a directory"):
        load_plan(tmp_path)


def test_the_module_docstring_example_is_a_valid_plan():
    import textwrap
    import tomllib

    import acquisition.plan as plan_mod

    block = textwrap.dedent(plan_mod.__doc__.split("::\n", 1)[1].split("\nEvery section", 1)[0])
    p = TestPlan.from_dict(tomllib.loads(block), source="acquisition.plan docstring")
    assert p.sim["hammer_tip"] == "medium" and p.exp_window().end_level == 0.01 and p.hammer["url"]
