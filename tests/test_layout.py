"""The package stays readable: no module under jaxskid/ over 500 lines, no function or method over 80 lines.

Lengths are read from the source with ``ast``: a module's length is its number of lines, a function's runs
from its ``def`` line to its last line (decorators not counted), nested functions included.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "jaxskid"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80
# Generated tables, exempt from the function limit, as "jaxskid/module.py:qualified.name" (none today).
GENERATED_TABLES: frozenset[str] = frozenset()


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def functions(tree: ast.AST, prefix: str = ""):
    """(qualified name, first line, number of lines) of every function and method, nested ones included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            name = f"{prefix}{node.name}"
            if not isinstance(node, ast.ClassDef):
                yield name, node.lineno, node.end_lineno - node.lineno + 1
            yield from functions(node, f"{name}.")
        else:
            yield from functions(node, prefix)


def test_the_package_has_modules():
    assert len(modules()) > 10, PACKAGE


def test_no_module_over_500_lines():
    too_long = []
    for path in modules():
        n = len(path.read_text().splitlines())
        if n > MAX_MODULE_LINES:
            too_long.append(f"{path.relative_to(PACKAGE.parent)}: {n} lines")
    assert not too_long, f"modules over {MAX_MODULE_LINES} lines:\n" + "\n".join(too_long)


def test_no_function_over_80_lines():
    too_long = []
    for path in modules():
        rel = path.relative_to(PACKAGE.parent).as_posix()
        for name, line, n in functions(ast.parse(path.read_text(), filename=str(path))):
            if n > MAX_FUNCTION_LINES and f"{rel}:{name}" not in GENERATED_TABLES:
                too_long.append(f"{rel}:{line} {name}: {n} lines")
    assert not too_long, f"functions over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(too_long)


def test_public_names_are_listed_once_for_import_and_once_for_type_checkers():
    """``jaxskid/__init__.py`` imports each public name on first use (``_LAZY``) and lists the same imports
    under ``TYPE_CHECKING`` for type checkers and editors: the two agree, and every name of ``__all__``
    resolves."""
    import jaxskid

    tree = ast.parse((PACKAGE / "__init__.py").read_text(encoding="utf-8"))
    (block,) = [node for node in tree.body if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING"]
    static = {}
    for node in block.body:
        assert isinstance(node, ast.ImportFrom), ast.unparse(node)
        module = "." * node.level + (node.module or "")
        for alias in node.names:
            static[alias.asname or alias.name] = f".{alias.name}" if module == "." else module
    assert static == jaxskid._LAZY
    for name in jaxskid.__all__:
        assert getattr(jaxskid, name) is not None, name
