"""The house rules, read off the source tree (no import of the package): file sizes, the README's size and
opening, the import graph (no cycles, layers run one way), and no private name reached across modules."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = "facepuppet"
MAX_LINES = 500
MAX_README = 12_000

# Layer of each top-level part of the package: a module may import its own part and parts of lower layers only.
LAYERS = {
    "errors": 0, "arkit": 0,
    "_util": 1,
    "io": 2, "filters": 2,
    "capture": 3, "mapping": 3, "synthesis": 3,
    "export": 4,
    "pipeline": 5,
    "live": 6, "batch": 6,
    "demo": 7, "characters": 7,
    "cli": 8,
}
TOP = {PACKAGE, f"{PACKAGE}.__main__"}          # the package's own face may import anything


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted((SRC / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES.get(name, Path()).name == "__init__.py"


def _imports(name: str, path: Path) -> list[tuple[str, str | None, int]]:
    """(module imported, name taken from it or None, line) for every import of the package, lazy ones too."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    base = name if _is_package(name) else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, None, node.lineno) for a in node.names if a.name.split(".")[0] == PACKAGE]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                mod = ".".join(anchor + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != PACKAGE:
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                if sub in MODULES:
                    out.append((sub, None, node.lineno))
                else:
                    out.append((mod, a.name, node.lineno))
    return out


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _part(name: str) -> str:
    return name.split(".")[1] if "." in name else ""


def test_source_files_are_small():
    big = {str(p.relative_to(ROOT)): n for p in MODULES.values()
           if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not big, f"files over {MAX_LINES} lines: {big}"


def test_readme_is_a_short_manual_opening_with_the_two_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text) <= MAX_README, len(text)
    blocks = [b.split("```", 1)[0].strip() for b in text.split("```sh")[1:3]]
    assert blocks[0].endswith("facepuppet demo"), blocks[0]
    assert blocks[1].endswith("pytest"), blocks[1]
    for banned in ("DESIGN.md", "../shared"):
        assert banned not in text, banned


def test_no_import_cycles():
    edges = {m: {t for t, _, _ in GRAPH[m] if t in MODULES and t != m} for m in MODULES}
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(edges[m]):
            if state.get(t) == 1:
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(MODULES):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_layers_run_one_way():
    wrong = []
    for m, imports in GRAPH.items():
        if m in TOP:
            continue
        here = _part(m)
        assert here in LAYERS, f"{m}: its part {here!r} has no layer in this test's table"
        for t, _, line in imports:
            there = _part(t)
            if there and there != here and LAYERS.get(there, 99) >= LAYERS[here]:
                wrong.append(f"{MODULES[m].relative_to(ROOT)}:{line} ({here}) imports {t} ({there})")
    assert not wrong, "imports against the layers:\n" + "\n".join(wrong)


def _private(word: str) -> bool:
    return word.startswith("_") and not (word.startswith("__") and word.endswith("__"))


def test_no_private_name_crosses_a_module():
    wrong = []
    for m, imports in GRAPH.items():
        for t, taken, line in imports:
            where = f"{MODULES[m].relative_to(ROOT)}:{line}"
            if taken is not None and _private(taken) and t != m:
                wrong.append(f"{where} takes {taken} from {t}")
            # a private module is for its own package: pkg._mod may be imported from inside pkg only
            parts = t.split(".")
            for i, p in enumerate(parts):
                if _private(p) and not (m + ".").startswith(".".join(parts[:i]) + "."):
                    wrong.append(f"{where} imports the private module {t}")
                    break
    assert not wrong, "\n".join(wrong)


def _own_names(tree: ast.AST) -> set[str]:
    """Private names a module defines itself: functions, classes, and attributes it assigns."""
    own = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            own.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            own.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            own.add(node.id)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            own.add(node.target.id)
    return {n for n in own if _private(n)}


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_private_attribute_of_another_module(name):
    """``x._name`` is fine only where this module defines ``_name`` itself (its own objects' privates)."""
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"))
    own = _own_names(tree)
    found = [f"line {n.lineno}: {ast.unparse(n)}" for n in ast.walk(tree)
             if isinstance(n, ast.Attribute) and _private(n.attr) and n.attr not in own
             and not (isinstance(n.value, ast.Name) and n.value.id in ("self", "cls"))]
    assert not found, found
