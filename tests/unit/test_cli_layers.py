"""Command line package shape: the top layer, no private names of the library, one job per module."""

import ast
import pathlib

import dampersim

PACKAGE = pathlib.Path(dampersim.__file__).parent
CLI = PACKAGE / "cli"


def imports(path):
    """(module, name) for every import in ``path``; name is None for ``import module``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, None
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                yield node.module, alias.name


def test_nothing_below_the_command_line_imports_it():
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if CLI in path.parents or path.name == "__main__.py" and path.parent == PACKAGE:
            continue
        for module, name in imports(path):
            if module == "dampersim.cli" or module.startswith("dampersim.cli.") or (module == "dampersim" and name == "cli"):
                offenders.append(f"{path.relative_to(PACKAGE)}: {module} {name or ''}")
    assert offenders == []


def test_command_line_uses_no_private_library_names():
    offenders = []
    for path in CLI.glob("*.py"):
        for module, name in imports(path):
            if not module.startswith("dampersim") or module == "dampersim.cli" or module.startswith("dampersim.cli."):
                continue
            private = [part for part in module.split(".") if part.startswith("_")]
            if private or (name and name.startswith("_")):
                offenders.append(f"{path.name}: {module} {name or ''}")
    assert offenders == []


def test_each_module_is_small_and_says_its_job():
    for path in CLI.glob("*.py"):
        text = path.read_text(encoding="utf-8")
        assert len(text.splitlines()) <= 600, path.name
        doc = ast.get_docstring(ast.parse(text))
        assert doc and doc.split(".")[0].strip(), path.name

