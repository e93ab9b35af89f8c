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



def module_name(path: Path, root: Path = PACKAGE) -> str:
    """The dotted name of the module at ``path`` in the package whose folder is ``root``."""
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(path: Path, known: set[str], root: Path = PACKAGE) -> set[str]:
    """The modules of ``known`` that ``path`` imports anywhere in it: at the top, inside functions and under
    ``TYPE_CHECKING``. ``from package import name`` imports the submodule ``package.name`` where there is
    one, else the package."""
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base)
    return {m for m in found if m in known and m != name}


def import_cycles(root: Path = PACKAGE) -> list[list[str]]:
    """Every cycle of the import graph of the modules under ``root``: the strongly connected components of
    two or more modules (Tarjan's algorithm), each as its modules, sorted."""
    paths = {module_name(p, root): p for p in sorted(root.rglob("*.py"))}
    graph = {m: sorted(imported_modules(p, set(paths), root)) for m, p in paths.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_no_import_cycle():
    """No module imports, directly or through others, a module that imports it back: imports inside
    functions count, since they only hide a cycle."""
    cycles = import_cycles()
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_the_cycle_finder_sees_imports_inside_functions(tmp_path):
    """The check itself, on packages made here: an import inside a function that closes a loop through a third
    module is a cycle, relative and absolute imports alike; the same imports without the loop are none."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .sub import b\n")
    (pkg / "sub" / "b.py").write_text("import pkg.c\n")
    (pkg / "c.py").write_text("def f():\n    from .a import x\n    return x\n")
    assert import_cycles(pkg) == [["pkg.a", "pkg.c", "pkg.sub.b"]]
    (pkg / "c.py").write_text("def f():\n    return 1\n")
    assert import_cycles(pkg) == []
