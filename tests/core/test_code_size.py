"""Issue 15's size check over the packages: no module over 600 lines, no function over 80 lines unless a comment
in it says why.

A function may be longer when a comment inside it starting ``# long`` says why (e.g. ``# long: one derivation whose
steps share every intermediate array``).  :data:`PENDING` names what is still over the limits and is being split
elsewhere; an entry that is no longer over the limit fails the test too, so the list only shrinks.
"""
import ast
import io
import pathlib
import tokenize

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGES = ("modalab", "acquisition", "identification", "updating", "hardware_sim")
MODULE_MAX = 600
FUNCTION_MAX = 80

#: over the limits today and being split elsewhere (path relative to the repository; a function as path::name);
#: empty: every module and function is within the limits, so any regression fails the test
PENDING: dict = {}


def _modules():
    for pkg in PACKAGES:
        yield from sorted((ROOT / pkg).rglob("*.py"))


def _comment_lines(text: str) -> dict:
    """Line number -> comment text of every comment in the source."""
    out = {}
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.COMMENT:
            out[tok.start[0]] = tok.string
    return out


def oversized(path: pathlib.Path, root: pathlib.Path = ROOT, module_max: int = MODULE_MAX,
              function_max: int = FUNCTION_MAX) -> list:
    """``(key, lines)`` for the module if it is over ``module_max`` lines and for each function over
    ``function_max`` lines (``def`` to its last line) without a ``# long`` comment inside it."""
    text = path.read_text(encoding="utf-8")
    rel = path.relative_to(root).as_posix()
    n = len(text.splitlines())
    out = [(rel, n)] if n > module_max else []
    comments = None
    for fn in ast.walk(ast.parse(text)):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        length = fn.end_lineno - fn.lineno + 1
        if length <= function_max:
            continue
        comments = _comment_lines(text) if comments is None else comments
        if not any(c.lstrip("# ").startswith("long") for ln, c in comments.items()
                   if fn.lineno <= ln <= fn.end_lineno):
            out.append((f"{rel}::{fn.name}", length))
    return out


def test_no_module_or_function_over_the_limits():
    over = [(k, n) for p in _modules() for k, n in oversized(p) if k not in PENDING]
    assert over == [], ("over the limits (split by what each part does, or say why in a '# long: ...' "
                        f"comment inside the function): {over}")


def test_pending_entries_are_still_over():
    found = {k for p in _modules() for k, _ in oversized(p)}
    stale = sorted(set(PENDING) - found)
    assert stale == [], f"no longer over the limits: remove {stale} from PENDING"


def test_the_check_sees_a_long_function_and_its_reason(tmp_path):
    body = "".join(f"    x{i} = {i}\n" for i in range(FUNCTION_MAX))
    bare = tmp_path / "bare.py"
    bare.write_text("def f():\n" + body)
    why = tmp_path / "why.py"
    why.write_text("def f():\n    # long: one table of constants\n" + body)
    assert oversized(bare, tmp_path) == [("bare.py::f", FUNCTION_MAX + 1)]
    assert oversized(why, tmp_path) == []
    assert oversized(bare, tmp_path, module_max=FUNCTION_MAX)[0] == ("bare.py", FUNCTION_MAX + 1)
