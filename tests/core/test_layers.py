"""The layering of the design is enforced by import-linter contracts in pyproject.toml."""
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_import_contracts_hold():
    pytest.importorskip("importlinter")
    exe = shutil.which("lint-imports")
    cmd = [exe] if exe else [sys.executable, "-m", "importlinter.cli"]
    r = subprocess.run(cmd + ["--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "broken" in r.stdout.lower() or "kept" in r.stdout.lower()


def test_the_contracts_are_the_two_layers_of_issue_15_without_exemptions():
    import tomllib

    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    contracts = cfg["contracts"]
    assert all(c["type"] == "layers" and "ignore_imports" not in c for c in contracts), contracts
    assert [c.get("layers") for c in contracts] == [
        ["modalab.app", "updating", "identification", "acquisition | hardware_sim", "modalab.core"],
        ["diagnosis", "methods", "correlation", "fe"]]
    assert contracts[1]["containers"] == ["updating"] and contracts[1].get("exhaustive") is True


def _cycles(graph) -> list:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    adj = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in graph.modules}
    index, low, on, stack, out = {}, {}, set(), [], []
    for root in sorted(adj):
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            v, i = work.pop()
            if i == 0:
                index[v] = low[v] = len(index)
                stack.append(v)
                on.add(v)
            if i < len(adj[v]):
                work.append((v, i + 1))
                w = adj[v][i]
                if w not in index:
                    work.append((w, 0))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
            if work:
                u = work[-1][0]
                low[u] = min(low[u], low[v])
    return out


def test_no_import_loops_between_modules():
    grimp = pytest.importorskip("grimp")
    graph = grimp.build_graph("modalab", "acquisition", "identification", "updating", "hardware_sim")
    assert _cycles(graph) == []          # TYPE_CHECKING imports count too


def test_the_loop_finder_sees_a_loop():
    class G:
        modules = {"a", "b", "c", "d"}
        edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}

        def find_modules_directly_imported_by(self, m):
            return self.edges[m]

    assert _cycles(G()) == [["a", "b", "c"]]



def test_each_stage_of_the_chain_has_one_file_that_the_readme_layout_names():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    layout = readme[readme.index("## Layout"):readme.index("\n## ", readme.index("## Layout") + 3)]
    for stage in ("acquire", "frf", "identify", "correlate", "update", "diagnose", "report"):
        assert (ROOT / "modalab" / "app" / "stages" / f"_{stage}.py").is_file(), stage
        assert f"_{stage}" in layout, stage
