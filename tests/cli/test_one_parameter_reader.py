"""Issue 15: one reader of the updating-parameter file, :func:`modalab.app.stages.load_parameters` (the parser
under it is :func:`updating.fe.parameter_file.read_parameter_file`); no other wrapper (``pipeline.load_params``,
``project.load_parameters`` were removed)."""
import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGES = ("modalab", "acquisition", "identification", "updating", "hardware_sim", "benchmarks")


def _sources():
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            yield str(f.relative_to(ROOT)), ast.parse(f.read_text(encoding="utf-8"))


def test_one_parameter_file_reader():
    defs, calls = [], []
    for rel, tree in _sources():
        defs += [rel for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
                 and n.name in ("load_params", "load_parameters", "read_parameters", "load_parameter_file")]
        calls += [rel for n in ast.walk(tree) if isinstance(n, ast.Call)
                  and getattr(n.func, "id", getattr(n.func, "attr", None)) == "read_parameter_file"]
    assert defs == ["modalab/app/stages/_common.py"]
    assert set(calls) <= {"modalab/app/stages/_common.py", "updating/fe/parameter_file.py"}, calls


def _error(tmp_path, text: str) -> tuple:
    """The parameter file ``text`` and the message :func:`load_parameters` refuses it with."""
    from modalab.app.stages import load_parameters
    from modalab.core.errors import PlanError

    f = tmp_path / "params.toml"
    f.write_text(text)
    with pytest.raises(PlanError) as e:
        load_parameters(f)
    return f, str(e.value)


def test_a_typo_is_one_line_with_the_file_the_key_and_the_closest_key(tmp_path):
    f, msg = _error(tmp_path, '[[parameter]]\nname = "E_wing"\nfeild = "E"\nproperties = ["wing"]\n')
    assert "\n" not in msg and str(f) in msg and "'feild'" in msg and "field" in msg


def test_a_bad_value_names_the_parameter_once(tmp_path):
    f, msg = _error(tmp_path, '[[parameter]]\nname = "E_wing"\nfield = "E"\nmode = "factr"\nproperties = ["wing"]\n')
    assert msg.startswith(f"{f}: parameter #1 ('E_wing'): ") and msg.count("E_wing") == 1 and "'factr'" in msg


def test_without_a_model_the_bounds_are_arrays(tmp_path):
    from modalab.app.stages import load_parameters

    f = tmp_path / "params.toml"
    f.write_text('[[parameter]]\nname = "E_wing"\nfield = "E"\nproperties = ["wing"]\nlower = 0.5\n')
    params, lo, hi = load_parameters(f)
    assert [p.name for p in params] == ["E_wing"] and lo.tolist() == [0.5] and hi.tolist() == [float("inf")]
