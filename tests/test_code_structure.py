"""Guards on how jaxloco's modules depend on each other, read from the source (no imports):
no import cycles, and no module using another package's private names."""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "jaxloco"


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()


@functools.cache
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


def _package(name: str, path: Path) -> str:
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def _imports(name: str, path: Path) -> list[tuple[str, str | None, int]]:
    """(module, imported name or None, line) for every import statement of a module, also
    those inside functions and `if TYPE_CHECKING:` blocks."""
    package = _package(name, path)
    found = []
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Import):
            found += [(a.name, None, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            for a in node.names:
                sub = f"{base}.{a.name}"
                found.append((sub, None, node.lineno) if sub in MODULES else (base, a.name, node.lineno))
    return found


def _graph() -> dict[str, set[str]]:
    return {name: {m for m, _, _ in _imports(name, path) if m in MODULES and m != name}
            for name, path in MODULES.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
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
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_modules_were_found():
    assert {"jaxloco.analysis", "jaxloco.sweep.runner", "jaxloco.robots.octopus.clm"} <= set(MODULES)


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycles():
    assert _cycles(_graph()) == []


def _is_private(attr: str) -> bool:
    return attr.startswith("_") and not attr.startswith("__")


def test_no_module_uses_another_packages_private_names():
    offenders = []
    for name, path in MODULES.items():
        package = _package(name, path)
        aliases = {}
        for module, imported, line in _imports(name, path):
            if module not in MODULES:
                continue
            other = _package(module, MODULES[module])
            if imported is not None and _is_private(imported) and other != package:
                offenders.append(f"{name}:{line} imports {module}.{imported}")
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.ImportFrom | ast.Import):
                for a in node.names:
                    base = node.module if isinstance(node, ast.ImportFrom) else None
                    full = f"{base}.{a.name}" if base else a.name
                    if full in MODULES:
                        aliases[a.asname or a.name.split(".")[-1]] = full
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
                module = aliases[node.value.id]
                if _is_private(node.attr) and _package(module, MODULES[module]) != package:
                    offenders.append(f"{name}:{node.lineno} uses {module}.{node.attr}")
    assert offenders == []


def test_packages_list_their_modules():
    """Each package's docstring names every module and subpackage in it (`name` in
    backquotes)."""
    missing = []
    for package in sorted(PACKAGE.rglob("__init__.py")):
        doc = ast.get_docstring(ast.parse(package.read_text(encoding="utf-8"))) or ""
        members = [m.stem for m in package.parent.glob("*.py") if m.stem != "__init__"]
        members += [d.name for d in package.parent.iterdir() if (d / "__init__.py").exists()]
        missing += [f"{package.parent.name}.{m}" for m in sorted(members) if f"`{m}`" not in doc]
    assert missing == []


def test_no_issue_numbers_in_code():
    """Code and specs say what and why, not which work item asked for it."""
    pattern = re.compile(r"\bissues?[ -]#?\d+", re.IGNORECASE)
    roots = [PACKAGE, PACKAGE.parent / "tests", PACKAGE.parent / "benchmarks"]
    found = [f"{path.relative_to(PACKAGE.parent)}:{n}"
             for root in roots for path in sorted(root.rglob("*")) if path.suffix in (".py", ".toml")
             for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1) if pattern.search(line)]
    assert found == []


def _robot_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[:2] == ["jaxloco", "robots"] else None


def test_robot_code_is_imported_only_by_its_own_robot_and_the_listed_importers():
    """The program cache keys a robot's programs by its own package's source and the
    rest of jaxloco (`jaxloco.sim.programs.source_digest`): sound only if no robot imports
    another robot and every module outside the robots that imports one is listed in
    `programs.ROBOT_IMPORTERS` (a pickle naming it counts every robot)."""
    from jaxloco.sim import programs

    importers = tuple(name.decode() for name in programs.ROBOT_IMPORTERS)
    offending = []
    for name, path in MODULES.items():
        own = _robot_of(name)
        for module, _, line in _imports(name, path):
            robot = _robot_of(module)
            if robot is None or robot == own:
                continue
            if own is not None or not name.startswith(importers):
                offending.append(f"{name}:{line} imports {module}")
    assert offending == []


def test_the_importer_guard_sees_a_robot_import():
    assert _robot_of("jaxloco.robots.snake.control") == "snake"
    assert _robot_of("jaxloco.sim.programs") is None
