"""The shape of the code: osmap_cli's imports form no cycle (imports inside functions count),
no module grows past 450 lines, and the shared modules know nothing of the commands above them.

Layers, bottom up: kernels (osmap_kernels); the shared modules (the modules at the top of
osmap_cli: errors, options, output, the image modules, provenance, records, batch, cluster, ...,
and the texture/ core); the commands (every other package: commands/ and one per command,
synth/, solid/, surface/, ...; and TOP_COMMAND_MODULES). Read from the source with ast; nothing
is imported.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "osmap_cli"
MAX_LINES = 450
SHARED_PACKAGES = ("osmap_cli.texture",)
# modules at the top that belong to the commands: the CLI, `osmap apply`'s logic, and the
# package's lazy public face
TOP_COMMAND_MODULES = ("osmap_cli", "osmap_cli.cli", "osmap_cli.apply")


def _modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


MODULES = _modules()


def _owner(name: str) -> str | None:
    """The module (or package) of MODULES that an imported dotted name lives in."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(name: str, path: Path) -> set[str]:
    """The osmap_cli modules NAME imports anywhere in its source, with the packages whose
    __init__ each import runs."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    targets = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            targets.update(f"{base}.{alias.name}" for alias in node.names)
            targets.add(base)
    found = set()
    for target in targets:
        owner = _owner(target) if target.startswith("osmap_cli") else None
        while owner:  # importing a.b.c runs a/__init__ and a/b/__init__ first
            found.add(owner)
            owner = owner.rpartition(".")[0]
    found.discard(name)
    return found


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _in_command_layer(name: str) -> bool:
    if name in TOP_COMMAND_MODULES:
        return True
    top = ".".join(name.split(".")[:2])
    return MODULES[top].name == "__init__.py" and top not in SHARED_PACKAGES


def _cycle() -> list[str] | None:
    """One import cycle as [a, b, ..., a], or None."""
    state: dict[str, int] = {}  # 1 on the path, 2 done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(GRAPH.get(node, ())):
            # a package importing its own submodules is how a package is built, not a cycle
            if node == nxt.rpartition(".")[0] and MODULES[node].name == "__init__.py":
                continue
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        path.pop()
        state[node] = 2
        return None

    for start in sorted(GRAPH):
        if start not in state and (found := visit(start)):
            return found
    return None


def test_the_graph_is_read():
    assert "osmap_cli.records" in GRAPH["osmap_cli.batch"]
    assert "osmap_cli.image_formats" in GRAPH["osmap_cli.image_read"]


def test_no_import_cycle():
    cycle = _cycle()
    assert cycle is None, " -> ".join(cycle)


def test_no_module_is_too_long():
    long = {name: n for name, path in MODULES.items()
            if (n := len(path.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_shared_modules_know_nothing_of_the_commands():
    upward = {name: sorted(t for t in targets if _in_command_layer(t) and t != "osmap_cli")
              for name, targets in GRAPH.items() if not _in_command_layer(name)}
    upward = {name: targets for name, targets in upward.items() if targets}
    assert not upward, f"shared modules importing a command's module: {upward}"


def test_every_package_is_installed():
    """pyproject.toml lists the packages by hand (kernels/ installs as osmap_kernels): a new
    subpackage missing there works in the editable install and fails after `pip install .`."""
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10 needs the tomli backport
        import tomli as tomllib

    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())
                 ["tool"]["setuptools"]["packages"])
    packages = {".".join(p.parent.relative_to(PACKAGE.parent).parts)
                for p in PACKAGE.rglob("__init__.py")}
    assert packages <= listed, sorted(packages - listed)
