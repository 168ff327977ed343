"""Every TOML the project ships goes through its real parser, and every shipped test plan drives a short
simulated acquisition (issue 14 #6: the demo project's plan was rejected for its own [sim] keys)."""
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from acquisition.plan import HAMMER_TIPS, load_plan
from modalab.app.stages import AcquireOptions, acquire, make_sim_backend

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p for d in ("examples", "modalab/app/demo_data") for p in (ROOT / d).rglob("*.toml"))
PLANS = [p for p in SHIPPED if "[roving]" in p.read_text()]


def _id(p):
    return str(p.relative_to(ROOT))


def test_the_lists_are_not_empty():
    # a rename or a move must not make the tests below vacuous
    assert len(PLANS) >= 7 and len(SHIPPED) >= len(PLANS) + 6


@pytest.mark.parametrize("path", SHIPPED, ids=_id)
def test_every_shipped_toml_passes_its_parser(path):
    if path in PLANS:
        plan = load_plan(path)
        assert plan.points and plan.channels
        return
    raw = tomllib.loads(path.read_text())
    if "parameter" in raw:                       # a parameter file of the updating stage
        from modalab.app.stages import load_parameters

        params, lo, hi = load_parameters(path)
        assert len(params) == len(raw["parameter"])
    else:                                        # a project file (it names a plan and the model)
        from modalab.app.project import load_project

        proj = load_project(path)
        if proj.plan_path is not None:
            load_plan(proj.plan_path)


def test_demo_data_copies_match_the_examples():
    for p in (ROOT / "modalab/app/demo_data/demo_project").glob("*"):
        twin = ROOT / "examples/demo_project" / p.name
        assert twin.exists() and twin.read_bytes() == p.read_bytes(), p.name


def test_simulator_knows_the_plan_tips():
    from hardware_sim.hammer import TIP_STIFFNESS_N_PER_M

    assert set(HAMMER_TIPS) == set(TIP_STIFFNESS_N_PER_M)


def _distinct_benches():
    """One plan per distinct simulated bench ([sim] section, channels, roving pattern): the demo_data copies
    are byte-identical to the examples (tested above) and plan.toml differs from plan_quick.toml only in
    its points and averages."""
    seen, out = set(), []
    for p in PLANS:
        d = tomllib.loads(p.read_text())
        key = repr((d.get("sim"), d.get("channels"), d.get("roving", {}).get("pattern"), d.get("hammer")))
        if key not in seen:
            seen.add(key)
            out.append(p)
    return out


@pytest.mark.parametrize("path", _distinct_benches(), ids=_id)
def test_every_shipped_plan_acquires_in_the_simulated_lab(path, tmp_path):
    # the shipped plan with its [sim] section as written, cut to one point and one hit
    d = tomllib.loads(path.read_text())
    d["roving"]["points"] = d["roving"]["points"][:1]
    d["acquisition"].update(averages=1, max_hits=1)
    if d.get("sim", {}).get("structure", "demo") != "demo":
        d["sim"]["structure"] = str((path.parent / d["sim"]["structure"]).resolve())
    plan_file = tmp_path / path.name
    plan_file.write_text(tomli_w.dumps(d))
    r = acquire(plan_file, tmp_path / "s", AcquireOptions(auto=True))
    sess, summary, exported = r.result.session, r.result.summary, r.result.uff
    assert summary.complete and exported is not None and summary.points[0].accepted == 1


def test_hammer_mass_and_tip_shape_the_force_pulse(tmp_path):
    # [sim] hammer_mass_kg / hammer_tip reach the simulator: contact time T = pi sqrt(m/k) (hardware_sim.hammer)
    from hardware_sim.hammer import TIP_STIFFNESS_N_PER_M

    base = ROOT / "examples/plans/demo_roving_hammer.toml"
    for tip, mass in (("soft", 1.0), ("hard", 0.16)):
        d = tomllib.loads(base.read_text())
        d["sim"].update(hammer_tip=tip, hammer_mass_kg=mass)
        f = tmp_path / f"{tip}.toml"
        f.write_text(tomli_w.dumps(d))
        lab = make_sim_backend(load_plan(f))
        T = np.pi * np.sqrt(mass / TIP_STIFFNESS_N_PER_M[tip])
        assert lab.hammer.tip == tip and lab.hammer.mass_kg == mass
        assert lab.hammer.contact_time_s == pytest.approx(T, rel=1e-12)
        pulses = lab.hammer.draw_pulses(np.random.default_rng(0), 50.0)
        assert pulses[0].width_s == pytest.approx(T, rel=0.15)      # 3 % width scatter
