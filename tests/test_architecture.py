"""The package's stages import each other exactly as docs/architecture.md draws them."""
import ast
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "lf_flame"
STAGES = ("optics", "simulate", "refocus", "real", "learn", "measure", "tomo", "recordings")


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


def code_edges() -> set[tuple[str, str]]:
    """Stage -> stage imports read from the code (relative and absolute, lazy ones too)."""
    edges = set()
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(ROOT).with_suffix("").parts
        package = list(rel[:-1])
        src = stage_of(".".join(rel))
        if src in (None, "__init__", "__main__"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                base = package[: len(package) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            targets = ([f"{module}.{a.name}" for a in node.names] if module == "lf_flame" else [module])
            for t in targets:
                dst = stage_of(t)
                if dst is not None and dst != src:
                    edges.add((src, dst))
    return edges


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
