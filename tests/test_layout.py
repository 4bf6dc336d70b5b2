"""The packages' layers and sizes (docs/architecture.md#which-part-may-import-which).

Read from the source with ``ast`` (imports inside functions count too), so a new import that
breaks a layer fails here, naming the module and what it imported.
"""

import ast
from pathlib import Path

import gyrohost
import gyrotensegrity

HOST = Path(gyrohost.__file__).parent
MODEL = Path(gyrotensegrity.__file__).parent
TESTS = Path(__file__).parent
BASE = {
    "errors",
    "geometry",
    "configfile",
    "config",
    "overlay",
    "resources",
    "sigint",
    "parallel",
    "gcfreeze",
}
ALLOWED = {
    "errors": set(),
    "geometry": set(),
    "sigint": set(),
    "gcfreeze": set(),
    "parallel": {"errors"},
    "resources": {"errors"},
    "overlay": {"errors"},
    "configfile": {"errors"},
    "config": {"errors", "resources", "overlay", "configfile"},
    "drivers": BASE | {"drivers"},
    "estimator": BASE | {"drivers", "estimator"},
    "control": BASE | {"estimator", "control"},
    "simrig": BASE | {"drivers", "simrig"},
    "bringup": BASE | {"drivers", "bringup"},
    "run": BASE | {"drivers", "estimator", "control", "simrig", "bringup", "run"},
    "plots": BASE | {"run", "control", "plots"},
    "sil": BASE | {"drivers", "estimator", "control", "simrig", "run", "plots", "sil"},
    "ident": BASE | {"estimator", "simrig", "run", "sil", "ident"},
    "bench": BASE | {"bench"},
    "sweep": BASE | {"control", "bench", "sweep"},
}
"""Top-level part of ``gyrohost`` -> the parts it may import. ``commands`` sits on top of them
all (any library part, never ``cli``); ``cli`` and ``__main__`` on top of ``commands``."""
TOP = {"commands", "cli", "__main__"}

MAX_FUNCTION_LINES = 60
"""A function's statements (its docstring aside) fit a screen: past that it holds more than one
step of its job, and each step deserves a name."""
MAX_METHODS = 25
"""A class with more methods than this holds more than one concept."""
LONG_FUNCTIONS = {
    "gyrohost/sil/emulator_keys.py:emulator_keys",
    "gyrohost/commands/identify.py:run",
    "gyrohost/commands/run.py:register",
    "gyrohost/commands/identify.py:register",
    "gyrohost/bench/peers.py:compare",
    "gyrotensegrity/structure.py:compile_structure",
    "gyrotensegrity/generators.py:prism_chain",
}
LARGE_CLASSES = {
    "gyrohost/simrig/wheel_emu.py:WheelBoardEmulator",
    "gyrohost/simrig/sim.py:SimulatedRig",
    "gyrohost/run/sequence.py:RunLoop",
}
"""Over the limits when the limits came, to be split: the lists may only shrink (an entry back
within its limit fails the test until it is struck off)."""


def part_of(module: str) -> str:
    return module.split(".")[1] if module.count(".") else ""


def imports(path: Path):
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
        elif isinstance(node, ast.Import):
            yield from (a.name for a in node.names)


def sources():
    """Every module of both packages with its name relative to the packages' parent."""
    for root in (HOST, MODEL):
        for path in sorted(root.rglob("*.py")):
            yield path, path.relative_to(root.parent)


def test_dependencies_point_down_only():
    broken = []
    for path in sorted(HOST.rglob("*.py")):
        rel = path.relative_to(HOST)
        part = rel.parts[0].removesuffix(".py")
        for module in imports(path):
            if not module.startswith("gyrohost.") or part not in ALLOWED:
                continue
            if part_of(module) not in ALLOWED[part] | {part}:
                broken.append(f"{rel} imports {module}")
    assert not broken, "imports against the layers:\n" + "\n".join(broken)


def test_library_never_imports_commands_or_cli():
    broken = [
        f"{path.relative_to(HOST)} imports {module}"
        for path in sorted(HOST.rglob("*.py"))
        if path.relative_to(HOST).parts[0].removesuffix(".py") not in TOP
        for module in imports(path)
        if part_of(module) in TOP
    ]
    assert not broken, "\n".join(broken)


def test_commands_never_import_the_cli():
    broken = [
        f"{path.relative_to(HOST)} imports {module}"
        for path in sorted((HOST / "commands").rglob("*.py"))
        for module in imports(path)
        if part_of(module) in ("cli", "__main__")
    ]
    assert not broken, "\n".join(broken)


def test_the_model_never_imports_the_host():
    broken = [
        f"{rel} imports {module}"
        for path, rel in sources()
        if rel.parts[0] == "gyrotensegrity"
        for module in imports(path)
        if module.split(".")[0] == "gyrohost"
    ]
    assert not broken, "\n".join(broken)


def test_neither_packages_nor_tests_import_studies():
    files = [path for path, _ in sources()] + sorted(TESTS.rglob("*.py"))
    broken = [
        f"{path} imports {module}"
        for path in files
        for module in imports(path)
        if module.split(".")[0] == "studies"
    ]
    assert not broken, "\n".join(broken)


def statement_lines(node) -> int:
    """Lines from a function's first statement after its docstring to its last."""
    body = node.body
    if isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]
    return body[-1].end_lineno - body[0].lineno + 1 if body else 0


def sizes():
    """``file:name`` -> (statement lines of each function, methods of each class)."""
    functions, classes = {}, {}
    for path, rel in sources():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            name = f"{rel.as_posix()}:{getattr(node, 'name', '')}"
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                functions[name] = max(functions.get(name, 0), statement_lines(node))
            elif isinstance(node, ast.ClassDef):
                defs = (ast.FunctionDef, ast.AsyncFunctionDef)
                classes[name] = sum(isinstance(b, defs) for b in node.body)
    return functions, classes


def test_functions_and_classes_hold_one_concept():
    functions, classes = sizes()
    long = {k for k, n in functions.items() if n > MAX_FUNCTION_LINES}
    large = {k for k, n in classes.items() if n > MAX_METHODS}
    assert long <= LONG_FUNCTIONS, (
        f"functions over {MAX_FUNCTION_LINES} lines: {long - LONG_FUNCTIONS}"
    )
    assert large <= LARGE_CLASSES, f"classes over {MAX_METHODS} methods: {large - LARGE_CLASSES}"
    split = (LONG_FUNCTIONS - long) | (LARGE_CLASSES - large)
    assert not split, f"within the limits now, strike off the list: {sorted(split)}"
