"""The package's layout keeps its shape: wings depend one way, the core never imports the lab
or the catalogue, and no core module imports another in a circle."""

import ast
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[1] / "kedfem"
#: a wing may import the wings listed (and itself, and the top-level errors module)
ALLOWED = {
    "model": set(),
    "motion": {"model"},
    "solvers": set(),
    "fe": {"model", "motion", "solvers"},
    "analysis": {"model", "motion", "solvers", "fe"},
    "io": {"model", "motion", "solvers", "fe", "analysis"},
    "lab": {"solvers"},
}


def _imports():
    """(importing module, imported module, at module level?) for every relative import."""
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        package = parts if parts[-1] == "__init__" else parts[:-1]
        package = [p for p in package if p != "__init__"]
        me = ".".join(p for p in parts if p != "__init__")
        tree = ast.parse(path.read_text())
        top = set(map(id, tree.body))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = package[: len(package) - node.level + 1]
                if node.module:
                    yield me, ".".join(base + [node.module]), id(node) in top
                else:
                    for a in node.names:
                        yield me, ".".join(base + [a.name]), id(node) in top
            elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "kedfem":
                yield me, node.module, id(node) in top  # an absolute import of kedfem's own
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] == "kedfem":
                        yield me, a.name, id(node) in top


def _wing(module):
    parts = module.split(".")
    return parts[1] if len(parts) >= 2 and parts[1] in ALLOWED else None


def test_wings_depend_one_way():
    # at module level and inside functions alike: a result is data that the io wing writes (the
    # analysis wing hands it over through kedfem.analysis.hooks, never by importing the io wing)
    bad = [(a, b) for a, b, _top in _imports()
           if _wing(a) and _wing(b) and _wing(a) != _wing(b) and _wing(b) not in ALLOWED[_wing(a)]]
    assert not bad, bad


def test_the_core_never_imports_the_lab():
    bad = [(a, b) for a, b, _ in _imports() if _wing(b) == "lab" and _wing(a) != "lab"]
    assert not bad, bad


def test_no_import_circle():
    """Not at module level, nor through imports inside functions (which Python tolerates, and which
    let results -> io.report -> mesh_check -> pipeline -> results and campbell <-> design_plots pass)."""
    g = nx.DiGraph((a, b) for a, b, _top in _imports() if a != b)
    # a package's __init__ importing its own modules is not a circle of concepts
    g.remove_edges_from([(a, b) for a, b in g.edges if b.startswith(a + ".")])
    assert list(nx.simple_cycles(g)) == []


def test_every_module_is_in_a_wing_or_named_top_level():
    top = {p.stem for p in ROOT.glob("*.py")}
    assert top == {"__init__", "errors", "checks", "catalogue", "trust", "cli", "cli_parser", "units"}, top
    assert {p.name for p in ROOT.iterdir() if p.is_dir() and p.name != "__pycache__"} == set(ALLOWED)


def test_no_module_is_a_big_room():
    """No module in kedfem/ above 800 lines (issue 27: the big rooms were split along their seams)."""
    sizes = {str(p.relative_to(ROOT.parent)): len(p.read_text().splitlines()) for p in ROOT.rglob("*.py")}
    big = {k: v for k, v in sizes.items() if v > 800}
    assert not big, big
