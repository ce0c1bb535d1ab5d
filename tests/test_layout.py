"""The package layout follows the data flow: imports point one way only."""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "ionav_viz"

# Lower layers first; a module may import only from its own layer or the ones before it.
LAYERS = ["core", "dataset", "sources", "nav", "learning", "experiment", "analysis", "sim", "viz", "api", "cli"]


def _layer(module: str) -> str | None:
    """The layer of a module (``ionav_viz.nav.ins`` -> ``nav``). The package itself, or a name
    taken from it (``from .. import __version__``), is its ``__init__``: it re-exports the API."""
    parts = module.split(".")
    if parts[0] != "ionav_viz":
        return None
    if len(parts) == 1 or not _is_module(parts[1]):
        return "api"
    return parts[1]


def _is_module(name: str) -> bool:
    return (PACKAGE / name).is_dir() or (PACKAGE / f"{name}.py").is_file()


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    return ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)


def _resolve(name: str) -> str:
    """``ionav_viz.nav.protocol.Estimate`` -> the module ``ionav_viz.nav.protocol``; a module stays."""
    parts = name.split(".")
    while len(parts) > 1:
        path = PACKAGE.parent.joinpath(*parts)
        if path.is_dir() or path.with_suffix(".py").is_file():
            return ".".join(parts)
        parts = parts[:-1]
    return "ionav_viz"


def _imports(path: Path) -> list[str]:
    """Every ionav_viz module or name ``path`` imports (absolute names), lazily inside functions
    too; every form: ``import ionav_viz.x``, ``from ionav_viz.x import y``, ``from .x import y``,
    ``from . import x``, ``from .. import x``."""
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    package = list(rel.parts[:-1])  # the package a module (or an __init__) belongs to
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out += [f"{target}.{a.name}" for a in node.names if target.startswith("ionav_viz")]
        elif isinstance(node, ast.Import):
            out += [a.name for a in node.names if a.name.startswith("ionav_viz")]
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the ionav_viz modules it imports (lazy imports too; the package's __init__ left
    out: it only re-exports names, lazily)."""
    graph: dict[str, set[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = _module_name(path)
        if name == "ionav_viz":
            continue
        graph[name] = {_resolve(t) for t in _imports(path)} - {name, "ionav_viz"}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (``[a, b, ..., a]``), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


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


def assert_probe_reported(tmp_path: Path, monkeypatch, source: str, check, *fragments: str) -> None:
    """A module ``nav/_probe.py`` holding ``source`` makes ``check`` fail with ``fragments`` in its
    message: the rule can fail. The probe goes into a copy of the package (the checks read
    :data:`PACKAGE`), never into the package itself, which tests running beside this one read."""
    copy = tmp_path / "ionav_viz"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__", "*.csv", "*.safetensors", "*.tsv"))
    monkeypatch.setitem(globals(), "PACKAGE", copy)
    (copy / "nav" / "_probe.py").write_text(source)
    try:
        check()
    except AssertionError as exc:
        assert all(f in str(exc) for f in fragments), str(exc)
    else:
        raise AssertionError(f"{check.__name__} did not report nav/_probe.py")


def test_the_check_catches_an_upward_import(tmp_path, monkeypatch):
    assert_probe_reported(tmp_path, monkeypatch, "from ..cli import app\n", test_imports_go_one_way_only, "nav/_probe.py imports ionav_viz.cli")


def test_the_check_reads_imports_of_the_package_itself(tmp_path, monkeypatch):
    """``from .. import __version__`` in nav imports the package's __init__, which re-exports the
    API: an arrow against the flow."""
    assert_probe_reported(tmp_path, monkeypatch, "def f():\n    from .. import __version__\n", test_imports_go_one_way_only,
                          "nav/_probe.py imports ionav_viz.__version__")


def test_no_import_circle():
    cycle = find_cycle(import_graph())
    assert cycle is None, " -> ".join(cycle or [])


def test_the_circle_check_finds_a_circle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    graph = import_graph()
    assert "ionav_viz.nav.protocol" in graph["ionav_viz.nav.ins"]  # lazy and module-level imports are both edges
    assert "ionav_viz.nav.ins" in graph["ionav_viz.experiment.registry"]


def _constants(path: Path) -> set[str]:
    """UPPER_CASE names assigned at the top level of a module."""
    names = set()
    for node in ast.parse(path.read_text()).body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        for target in targets:
            for name in [target] if isinstance(target, ast.Name) else getattr(target, "elts", []):
                if isinstance(name, ast.Name) and name.id.isupper() and len(name.id) > 1:
                    names.add(name.id)
    return names


def test_every_constant_has_one_home():
    """An UPPER_CASE module constant is assigned in one module of the package (no second copy, no
    alias such as ``RATE_HZ = GRID_RATE_HZ``), and is imported from that module (no re-export)."""
    homes: dict[str, list[str]] = {}
    defined: dict[str, set[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        names = _constants(path)
        defined[_module_name(path)] = names
        for name in names:
            homes.setdefault(name, []).append(str(path.relative_to(PACKAGE)))
    twice = {name: where for name, where in homes.items() if len(where) > 1}
    assert not twice, twice
    through = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for target in _imports(path):
            module, _, name = target.rpartition(".")
            if name.isupper() and len(name) > 1 and module in defined and name not in defined[module]:
                through.append(f"{path.relative_to(PACKAGE)} imports {name} from {module}, which does not define it")
    assert not through, through


def test_the_constant_check_finds_a_copy_and_a_re_export(tmp_path, monkeypatch):
    assert_probe_reported(tmp_path / "a", monkeypatch, "GRID_RATE_HZ = 10.0\n", test_every_constant_has_one_home, "GRID_RATE_HZ", "nav/_probe.py")
    monkeypatch.undo()
    assert_probe_reported(tmp_path / "b", monkeypatch, "from .windows import WINDOW_S\n", test_every_constant_has_one_home, "imports WINDOW_S from ionav_viz.nav.windows")


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
