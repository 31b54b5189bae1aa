"""The package's stages import each other exactly as docs/architecture.md draws them, and no
modules of the package import each other (no circle of imports)."""
import ast
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "lf_flame"
STAGES = ("optics", "simulate", "refocus", "real", "learn", "measure", "tomo", "temperature", "recordings")


def drawn_edges() -> set[tuple[str, str]]:
    """The arrows of the mermaid graph in docs/architecture.md (``a --> b & c``)."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = re.search(r"```mermaid\n(.*?)```", text, re.S).group(1)
    edges = set()
    for line in block.splitlines():
        if "-->" in line:
            src, dst = line.split("-->")
            edges |= {(src.strip(), d.strip()) for d in dst.split("&")}
    return edges


def stage_of(module: str) -> str | None:
    """``lf_flame.tomo.operator`` -> ``tomo``; ``lf_flame.config`` -> ``config``."""
    parts = module.split(".")
    return parts[1] if parts[0] == "lf_flame" and len(parts) > 1 else None


def module_name(path: Path) -> str:
    """``lf_flame/tomo/operator.py`` -> ``lf_flame.tomo.operator``; ``lf_flame/tomo/__init__.py`` -> ``lf_flame.tomo``."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_names(path: Path) -> set[str]:
    """Absolute dotted names a file imports, at any depth (function-level imports too): ``import a.b``
    gives ``a.b``; ``from a import b, c`` gives ``a.b`` and ``a.c``, a relative ``from`` resolved
    against the file's package."""
    rel = path.relative_to(ROOT).with_suffix("").parts
    package = list(rel[:-1])
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            names |= {f"{module}.{a.name}" for a in node.names}
    return names


def code_edges() -> set[tuple[str, str]]:
    """Stage -> stage imports read from the code (relative and absolute, lazy ones too)."""
    edges = set()
    for path in PACKAGE.rglob("*.py"):
        src = stage_of(".".join(path.relative_to(ROOT).with_suffix("").parts))
        if src in (None, "__init__", "__main__"):
            continue
        for t in imported_names(path):
            dst = stage_of(t)
            if dst is not None and dst != src:
                edges.add((src, dst))
    return edges


def lazy_exports(path: Path) -> dict[str, str]:
    """Name -> the submodule that defines it, of a package ``__init__`` that re-exports lazily
    (``lazy.attach(..., submod_attrs={...})``); empty for any other file."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.keyword) and node.arg == "submod_attrs":
            return {name: sub for sub, names in ast.literal_eval(node.value).items() for name in names}
    return {}


def module_graph() -> dict[str, set[str]]:
    """Each module of the package -> the package's modules it imports. A name imported from a
    module counts as that module; one a package re-exports lazily, as the submodule defining it."""
    files = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    exports = {m: lazy_exports(p) for m, p in files.items() if p.name == "__init__.py"}

    def resolve(name: str) -> str | None:
        if name in files:
            return name
        parent, _, attr = name.rpartition(".")
        if attr in exports.get(parent, {}):
            return f"{parent}.{exports[parent][attr]}"
        return parent if parent in files else None

    return {m: {t for t in map(resolve, imported_names(p)) if t is not None and t != m} for m, p in files.items()}


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The circles of an import graph: its strongly connected components of more than one
    module (Tarjan), each sorted; two modules that import each other make one."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(cycles)


def test_the_code_imports_across_stages_exactly_as_drawn():
    drawn, code = drawn_edges(), code_edges()
    assert drawn, "no mermaid graph found in docs/architecture.md"
    assert code - drawn == set(), f"imports between stages that docs/architecture.md does not draw: {code - drawn}"
    assert drawn - code == set(), f"arrows in docs/architecture.md that no import makes: {drawn - code}"


def test_the_lowest_stages_import_no_other_stage():
    sources = {s for s, _ in code_edges()}
    assert "optics" not in sources and "refocus" not in sources


@pytest.mark.parametrize("stage", STAGES)
def test_every_name_a_stage_exports_resolves(stage):
    """Each sub-package's lazy re-exports name real objects of its modules."""
    pkg = importlib.import_module(f"lf_flame.{stage}")
    assert pkg.__doc__ and len(pkg.__all__) > 1
    for name in pkg.__all__:
        assert getattr(pkg, name) is not None


def test_no_modules_import_each_other():
    """No circle of imports between the package's modules (function-level imports included)."""
    graph = module_graph()
    assert len(graph) > 50 and "lf_flame.simulate.scenes" in graph["lf_flame.simulate.scenes_volume"]
    mutual = sorted((a, b) for a in graph for b in graph[a] if a < b and a in graph.get(b, ()))
    assert mutual == [], f"modules that import each other: {mutual}"
    assert import_cycles(graph) == [], f"circles of imports: {import_cycles(graph)}"


def test_the_import_checks_catch_what_they_should():
    """Imports inside functions and relative ones are read; a lazily re-exported name resolves to
    its submodule; the cycle search finds pairs and longer circles, not chains."""
    module = PACKAGE / "simulate" / "scenes_volume.py"
    assert "lf_flame.simulate.layers.Scene" in imported_names(module)
    assert lazy_exports(PACKAGE / "tomo" / "__init__.py")["reconstruct"] == "solvers"
    assert {"lf_flame.temperature.pyrometry"} <= module_graph()["lf_flame.cli.temperature"]   # function-level
    assert import_cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == [["a", "b", "c"]]
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []
