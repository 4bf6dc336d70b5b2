"""The host package's layers: dependencies point down only (docs/architecture.md).

Read from the source with ``ast`` (imports inside functions count too), so a new import that
breaks a layer fails here, naming the module and what it imported.
"""

import ast
from pathlib import Path

import gyrohost

ROOT = Path(gyrohost.__file__).parent
BASE = {"errors", "geometry", "config", "overlay", "resources", "sigint", "parallel", "gcfreeze"}
ALLOWED = {
    "errors": set(),
    "geometry": set(),
    "sigint": set(),
    "gcfreeze": set(),
    "parallel": {"errors"},
    "resources": {"errors"},
    "overlay": {"errors"},
    "config": {"errors", "resources", "overlay"},
    "drivers": BASE | {"drivers"},
    "estimator": BASE | {"drivers", "estimator"},
    "control": BASE | {"estimator", "control"},
    "rig": BASE | {"drivers", "rig"},
    "bringup": BASE | {"drivers", "bringup"},
    "run": BASE | {"drivers", "estimator", "control", "rig", "bringup", "run"},
    "plots": BASE | {"run", "control", "plots"},
    "ident": BASE | {"estimator", "rig", "run", "ident"},
    "bench": BASE | {"bench"},
    "sweep": BASE | {"control", "bench", "sweep"},
}
"""Top-level part of ``gyrohost`` -> the parts it may import. ``experiments``, ``commands``,
``cli`` and ``__main__`` sit on top and may import anything but each other's modules."""


def part_of(module: str) -> str:
    return module.split(".")[1] if module.count(".") else ""


def imports(path: Path):
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
        elif isinstance(node, ast.Import):
            yield from (a.name for a in node.names)


def test_dependencies_point_down_only():
    broken = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        part = rel.parts[0].removesuffix(".py")
        for module in imports(path):
            if not module.startswith("gyrohost.") or part not in ALLOWED:
                continue
            if part_of(module) not in ALLOWED[part] | {part}:
                broken.append(f"{rel} imports {module}")
    assert not broken, "imports against the layers:\n" + "\n".join(broken)


def test_library_never_imports_experiments_or_commands():
    top = {"experiments", "commands", "cli.py", "__main__.py"}
    broken = [
        f"{path.relative_to(ROOT)} imports {module}"
        for path in sorted(ROOT.rglob("*.py"))
        if path.relative_to(ROOT).parts[0] not in top
        for module in imports(path)
        if part_of(module) in ("experiments", "commands", "cli")
    ]
    assert not broken, "\n".join(broken)


def test_no_module_over_500_lines():
    long = {
        str(p.relative_to(ROOT)): n
        for p in ROOT.rglob("*.py")
        if (n := len(p.read_text().splitlines())) > 500
    }
    assert not long, f"modules over 500 lines: {long}"
