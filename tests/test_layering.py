"""Imports point one way: cli/api/commands -> (train, track, refine) -> the shared modules (model, mesh, io,
imaging, detector, search, result, metrics, models, errors) -> _kernels; train, track and refine do not import each
other; benchmarks/ has no import cycle."""

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PKG = REPO / "aamtrack"
TOP = {"cli", "api", "commands", "__init__", "__main__"}
MIDDLE = {"train", "track", "refine"}


def _layer(part: str) -> int:
    if part in TOP:
        return 3
    if part in MIDDLE:
        return 2
    if part == "_kernels":
        return 0
    return 1


def _imports(path: Path) -> list[str]:
    """Absolute dotted names of the aamtrack modules a file imports."""
    rel = path.relative_to(REPO).with_suffix("")
    package = list(rel.parts[:-1]) if rel.name != "__init__" else list(rel.parts[:-1])
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names.append(mod)
        elif isinstance(node, ast.Import):
            names += [a.name for a in node.names]
    return [n for n in names if n == "aamtrack" or n.startswith("aamtrack.")]


def _part(dotted: str) -> str:
    parts = dotted.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


@pytest.mark.parametrize("path", sorted(PKG.rglob("*.py")), ids=lambda p: str(p.relative_to(PKG)))
def test_imports_point_one_way(path):
    src = _part(".".join(path.relative_to(REPO).with_suffix("").parts))
    for target in _imports(path):
        dst = _part(target)
        if dst == src or target == "aamtrack":
            continue
        assert _layer(dst) <= _layer(src), f"{path.relative_to(REPO)} imports {target}: against the layering"
        if _layer(src) == 2 and _layer(dst) == 2:
            pytest.fail(f"{path.relative_to(REPO)} imports {target}: train, track and refine are independent")


def test_benchmarks_have_no_import_cycle():
    mods = {p.stem: p for p in (REPO / "benchmarks").glob("*.py")}
    graph = {}
    for name, path in mods.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module in mods:
                deps.add(node.module)
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name in mods}
        graph[name] = deps
    seen, stack = set(), []

    def visit(n):
        assert n not in stack, f"import cycle in benchmarks/: {' -> '.join(stack[stack.index(n):] + [n])}"
        if n in seen:
            return
        stack.append(n)
        for m in graph[n]:
            visit(m)
        stack.pop()
        seen.add(n)

    for n in graph:
        visit(n)
