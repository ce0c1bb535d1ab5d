"""The package layout follows the data flow: imports point one way only."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "ionav_viz"

# Lower layers first; a module may import only from its own layer or the ones before it.
LAYERS = ["core", "dataset", "sources", "nav", "analysis", "sim", "viz", "api", "cli"]


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "ionav_viz" else None


def _imports(path: Path) -> list[str]:
    """Every ionav_viz module ``path`` imports (absolute names), lazily inside functions too."""
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    package = list(rel.parts[:-1])  # the package a module (or an __init__) belongs to
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
                names = [target] if node.module else [f"{target}.{a.name}" for a in node.names]
            else:
                names = [node.module or ""]
            out += [n for n in names if n.startswith("ionav_viz")]
        elif isinstance(node, ast.Import):
            out += [a.name for a in node.names if a.name.startswith("ionav_viz")]
    return out


def test_imports_go_one_way_only():
    wrong = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        own = rel.parts[0].removesuffix(".py")
        if own not in LAYERS:
            continue  # the package's __init__ (lazy re-exports)
        for target in _imports(path):
            layer = _layer(target)
            if layer is None or layer not in LAYERS:
                continue
            if LAYERS.index(layer) > LAYERS.index(own):
                wrong.append(f"{rel} imports {target}")
    assert not wrong, "\n".join(wrong)


def test_the_check_catches_an_upward_import(tmp_path, monkeypatch):
    # the rule above must be able to fail: a nav module importing the CLI is reported
    fake = PACKAGE / "nav" / "_layer_probe.py"
    fake.write_text("from ..cli import app\n")
    try:
        try:
            test_imports_go_one_way_only()
        except AssertionError as exc:
            assert "nav/_layer_probe.py imports ionav_viz.cli" in str(exc)
        else:
            raise AssertionError("an upward import was not reported")
    finally:
        fake.unlink()


def test_every_subpackage_says_what_it_is():
    for layer in LAYERS:
        init = PACKAGE / layer / "__init__.py"
        if init.exists():
            assert (ast.get_docstring(ast.parse(init.read_text())) or "").strip(), f"{layer}/__init__.py has no docstring"


def test_benchmarks_and_tests_use_no_private_names():
    root = PACKAGE.parent
    private = []
    for path in list((root / "benchmarks").glob("*.py")) + list((root / "tests").glob("*.py")) + list((root / "examples").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("ionav_viz"):
                private += [f"{path.name}: {node.module}.{a.name}" for a in node.names if a.name.startswith("_")]
    assert not private, private
