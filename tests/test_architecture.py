"""The house keeps its shape: every part of the package on the map, the data-flow
figure's arrows backed by imports, no import circle, no private name imported
across modules, no module over 500 lines and no function over 120
(studies/architecture.py draws the map; docs/architecture.md)."""
import ast

import architecture   # studies/: tests/conftest.py puts it on sys.path

MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 120


def test_every_part_of_the_package_is_on_the_map_with_its_docstring():
    parts = {p.stem for p in architecture.PACKAGE.iterdir()
             if (p.is_dir() and (p / "__init__.py").exists())
             or (p.suffix == ".py" and p.name != "__init__.py")}
    assert parts == set(architecture.PARTS)
    for path in architecture.PACKAGE.rglob("*.py"):
        if "__pycache__" not in path.parts and path.stat().st_size:
            assert ast.get_docstring(ast.parse(path.read_text())), path


def test_the_data_flow_arrows_are_imports():
    assert architecture.check_flow(architecture.imports()) == []


def test_no_import_circle():
    """No two modules of the package import each other, directly or through others
    (Tarjan's strongly connected components on the module graph)."""
    graph = architecture.imports()
    modules = set(graph)
    # a module reading its own package (``from symcushion import __version__``) is not
    # a circle of concepts: Python runs a package's __init__ before its modules anyway
    edges = {m: {t for t in targets if t in modules and t != m and not m.startswith(t + ".")}
             for m, targets in graph.items()}
    index, low, stack, on_stack, circles, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(component)

    for v in sorted(modules):
        if v not in index:
            visit(v)
    assert circles == []


def test_no_private_name_is_imported_across_modules():
    crossing = []
    for path in architecture.PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("symcushion"):
                crossing += [f"{path.name}: {node.module}.{a.name}" for a in node.names
                             if a.name.startswith("_") and not a.name.startswith("__")]
    assert crossing == []


def test_modules_and_functions_are_short_enough_to_read_at_once():
    long_modules = [(p.name, n) for p in architecture.PACKAGE.rglob("*.py")
                    if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES]
    assert long_modules == []
    lines, module, name = architecture.function_lengths()[0]
    assert lines <= MAX_FUNCTION_LINES, (module, name)


def test_the_map_in_the_docs_is_the_code_s():
    """docs/architecture.md's folder table and public API are those the code gives
    (``python studies/architecture.py`` writes them)."""
    doc = architecture.DOC.read_text()
    assert architecture.folder_table() in doc
    assert architecture.api_list() in doc
