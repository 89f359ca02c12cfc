"""Shape of the code base: small modules that say their job, no private names across packages.

The layer order itself is an import-linter contract in pyproject.toml, checked by
``make test`` (``lint-imports``); these tests cover what that contract cannot express.
"""

import ast
import pathlib

import dampersim

PACKAGE = pathlib.Path(dampersim.__file__).parent
ROOT = PACKAGE.parent
#: The longest module we accept [lines]: beyond it a module holds more than one job.
MAX_LINES = 600


def sources():
    """Every Python module of the library, the dashboard pages and the app."""
    yield from sorted(PACKAGE.rglob("*.py"))
    yield from sorted((ROOT / "pages").glob("*.py"))
    yield ROOT / "app.py"


def private(name: str) -> bool:
    """An underscore name that is not a dunder (``__version__`` is public)."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def owner(module: str) -> str:
    """The subpackage (or top-level module) of dampersim that ``module`` belongs to."""
    parts = module.split(".")
    return ".".join(parts[:2])


def module_name(path: pathlib.Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def test_each_module_is_small_and_says_its_job():
    problems = []
    for path in sources():
        text = path.read_text(encoding="utf-8")
        n = len(text.splitlines())
        if n > MAX_LINES:
            problems.append(f"{path.relative_to(ROOT)}: {n} lines")
        doc = ast.get_docstring(ast.parse(text))
        if not doc or not doc.split(".")[0].strip():
            problems.append(f"{path.relative_to(ROOT)}: no docstring saying its job")
    assert problems == []


def test_no_package_imports_a_private_name_of_another():
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        here = owner(module_name(path))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ImportFrom) or node.level or not (node.module or "").startswith("dampersim."):
                continue
            if owner(node.module) == here:
                continue
            names = [p for p in node.module.split(".") if private(p)] + [a.name for a in node.names if private(a.name)]
            if names:
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.module} {names}")
    assert offenders == []


def test_the_library_never_imports_the_command_line_or_the_dashboard():
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        name = module_name(path)
        if name.startswith("dampersim.cli") or name == "dampersim.__main__":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            mods = []
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                mods = [node.module or ""]
            for m in mods:
                if m.split(".")[0] in ("dash", "pages", "app") or m.startswith("dampersim.cli"):
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}: {m}")
    assert offenders == []
