"""Structure of the first-party code: no import cycles between modules, and no oversized module in uh_runtime.

Every module of every first-party package (a top-level folder ``uh_*`` holding a folder of the same
name; ``uh_msgs`` is not Python) is parsed with ``ast``; each import of a first-party module, at
module level or inside a function, relative ones resolved, is an edge of the module import graph.
Importing ``pkg.mod`` counts as importing that module (the package's ``__init__`` that Python runs
first is not an edge, or every package re-exporting its modules would be a cycle).
"""
import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: Longest module of uh_runtime, in lines.
MAX_RUNTIME_MODULE_LINES = 600


def _package_roots() -> dict:
    """``{package name: folder of the package}`` of every first-party Python package."""
    return {d.name: d / d.name for d in sorted(REPO.glob('uh_*'))
            if d.is_dir() and d.name != 'uh_msgs' and (d / d.name).is_dir()}


def _modules(roots: dict) -> dict:
    """``{dotted module name: (path, is package __init__)}`` of every module of ``roots``."""
    found = {}
    for name, root in roots.items():
        for path in sorted(root.rglob('*.py')):
            parts = [name, *path.relative_to(root).with_suffix('').parts]
            is_init = parts[-1] == '__init__'
            if is_init:
                parts.pop()
            found['.'.join(parts)] = (path, is_init)
    return found


def _imported(module: str, is_init: bool, tree: ast.AST):
    """Every dotted name ``tree`` imports (``from a import b`` gives ``a.b`` and ``a``)."""
    package = module.split('.') if is_init else module.split('.')[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, None
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                up = package[:len(package) - (node.level - 1)]
                base = '.'.join([*up, base] if base else up)
            for alias in node.names:
                yield base, f'{base}.{alias.name}'


def import_graph() -> dict:
    """Return ``{module: set of first-party modules it imports}``."""
    modules = _modules(_package_roots())

    def known(name):
        """Return the module ``name`` refers to: itself, or its closest enclosing module."""
        while name and name not in modules:
            name = name.rpartition('.')[0]
        return name or None

    graph = {}
    for module, (path, is_init) in modules.items():
        edges = set()
        for base, member in _imported(module, is_init, ast.parse(path.read_text(), str(path))):
            target = member if member in modules else known(base)
            if target and target != module:
                edges.add(target)
        graph[module] = edges
    return graph


def find_cycle(graph: dict):
    """One cycle of ``graph`` as ``[m1, m2, ..., m1]``, or None."""
    state = {}   # module -> 1 on the current path, 2 done

    def visit(module, path):
        state[module] = 1
        path.append(module)
        for target in sorted(graph.get(module, ())):
            if state.get(target) == 1:
                return path[path.index(target):] + [target]
            if target not in state:
                cycle = visit(target, path)
                if cycle:
                    return cycle
        path.pop()
        state[module] = 2
        return None

    for module in sorted(graph):
        if module not in state:
            cycle = visit(module, [])
            if cycle:
                return cycle
    return None


def test_the_packages_are_found():
    roots = _package_roots()
    assert {'uh_runtime', 'uh_topology', 'uh_sim_node', 'uh_controller_node', 'uh_bringup'} <= set(roots)
    assert 'uh_msgs' not in roots
    graph = import_graph()
    # relative imports (one and two levels up) and imports inside functions are edges
    assert 'uh_runtime.dds_backend.node' in graph['uh_runtime.dds_backend']
    assert 'uh_runtime.graph' in graph['uh_runtime.dds_backend.node']
    assert 'uh_runtime.graph' in graph['uh_runtime.cli']


def test_the_cycle_finder_names_a_cycle():
    assert find_cycle({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': set()}) == ['a', 'b', 'c', 'a']
    assert find_cycle({'a': {'b'}, 'b': set()}) is None


def test_no_import_cycle_between_first_party_modules():
    cycle = find_cycle(import_graph())
    assert cycle is None, 'import cycle: ' + ' -> '.join(cycle)


@pytest.mark.parametrize('path', sorted((REPO / 'uh_runtime' / 'uh_runtime').rglob('*.py')),
                         ids=lambda p: str(p.relative_to(REPO)))
def test_no_runtime_module_is_oversized(path):
    lines = len(path.read_text().splitlines())
    assert lines <= MAX_RUNTIME_MODULE_LINES, (
        f'{path.relative_to(REPO)} has {lines} lines (at most {MAX_RUNTIME_MODULE_LINES}): split it')
