"""Structure of the first-party code: no import cycles between modules, no oversized module or function.

Besides the import graph: uh_runtime's modules have at most 600 lines, node modules (``*_node.py``)
at most 200, functions at most 80 without their docstring; first-party imports are at the top of
modules except where an allowlist below says why; no module imports a private name (a leading
underscore) of another package. The allowlists name what is still over, so that they can only shrink.

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
#: Longest node module (``*_node.py``: message in, message out), in lines.
MAX_NODE_MODULE_LINES = 200
#: Longest function, in lines without its docstring.
MAX_FUNCTION_LINES = 80

#: ``path:function`` of the functions still longer than MAX_FUNCTION_LINES (being split).
LONG_FUNCTIONS: set = set()

_HEAVY_CLI = 'loads Cyclone DDS and every message type: uh --help and a mistyped command answer at once'
#: ``path:function`` that import first-party modules inside the function, and why.
LAZY_IMPORTS = {
    # uh_runtime: the backend is chosen at run time, and its command-line tools start fast
    'uh_runtime/uh_runtime/cli/uh.py:_graph': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:cmd_topic_info': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:_reader': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:cmd_topic_echo': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:cmd_topic_hz': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:_value_text': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:cmd_param_set': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:__init__': _HEAVY_CLI,
    'uh_runtime/uh_runtime/cli/uh.py:call': _HEAVY_CLI,
    'uh_runtime/uh_runtime/dds/endpoints.py:__init__': 'the CDR codec only where an endpoint is created',
    'uh_runtime/uh_runtime/dds/node.py:__init__': 'parameter services only when a node is created',
    'uh_runtime/uh_runtime/dds/node.py:create_service': 'services only when a service is created',
    'uh_runtime/uh_runtime/runner.py:check_parameter_overrides': 'the package imports the runner: no cycle at import',
    'uh_runtime/uh_runtime/runner.py:_clear_errors': 'the package imports the runner: no cycle at import',
    'uh_runtime/uh_runtime/runner.py:run_node': 'process statistics only when asked for',
    'uh_team/uh_team/team_simulation.py:run_team_simulation': 'the numba team loop only for its engine: the object '
                                                               'loop also runs on compiled kernels, without numba',
    'uh_team/uh_team/team_simulation.py:_run_kernel': 'as run_team_simulation',
}

#: ``path: {names}`` of private names still imported from another package (to be made public at home).
PRIVATE_IMPORTS: dict = {}


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
    assert 'uh_runtime.dds.graph' in graph['uh_runtime.dds.node']
    assert 'uh_runtime.messages' in graph['uh_runtime.dds.node']
    assert 'uh_runtime.dds.graph' in graph['uh_runtime.cli.uh']
    # a sub-package's __init__ names its modules only as strings (uh_runtime.lazy_exports): no edges
    assert graph['uh_runtime.dds'] == {'uh_runtime.lazy_exports'}


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


def _sources():
    """``(path relative to the repository, package name, syntax tree)`` of every first-party module."""
    for name, root in _package_roots().items():
        for path in sorted(root.rglob('*.py')):
            yield path.relative_to(REPO).as_posix(), name, ast.parse(path.read_text(), str(path))


def _functions(tree: ast.AST):
    """Every function and method of ``tree``, nested ones included."""
    return [node for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))]


def function_lines(function) -> int:
    """Return the lines of ``function`` (an ``ast`` function) without its docstring."""
    lines = function.end_lineno - function.lineno + 1
    first = function.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        lines -= first.end_lineno - first.lineno + 1
    return lines


def first_party_imports_inside(function, packages) -> list:
    """Return the first-party modules ``function`` imports in its body (relative imports are first-party)."""
    found = []
    for node in ast.walk(function):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or '').split('.')[0] in packages):
            found.append('.' * node.level + (node.module or ''))
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.split('.')[0] in packages]
    return found


def private_imports(package: str, tree: ast.AST, packages) -> set:
    """Return ``module.name`` of every private name ``tree`` imports from another first-party package."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and not node.level and node.module:
            home = node.module.split('.')[0]
            if home in packages and home != package:
                found |= {f'{node.module}.{a.name}' for a in node.names
                          if a.name.startswith('_') and not a.name.startswith('__')}
    return found


def test_the_structure_checks_see_what_they_look_for():
    tree = ast.parse('def f():\n    """Doc\n\n    string."""\n    from uh_core import layout\n    return 1\n'
                     'from uh_topology.scenario import _private, public\n')
    [f] = _functions(tree)
    assert function_lines(f) == 3
    assert first_party_imports_inside(f, {'uh_core'}) == ['uh_core']
    assert private_imports('uh_campaign', tree, {'uh_topology'}) == {'uh_topology.scenario._private'}
    assert private_imports('uh_topology', tree, {'uh_topology'}) == set()


@pytest.mark.parametrize('path', sorted(REPO.glob('uh_*/uh_*/**/*_node.py')), ids=lambda p: str(p.relative_to(REPO)))
def test_no_node_module_is_oversized(path):
    lines = len(path.read_text().splitlines())
    assert lines <= MAX_NODE_MODULE_LINES, (
        f'{path.relative_to(REPO)} has {lines} lines (at most {MAX_NODE_MODULE_LINES}): move what is not '
        'message in, message out into a ROS-free module')


def test_no_function_is_oversized():
    over = {f'{path}:{f.name}': function_lines(f) for path, _, tree in _sources() for f in _functions(tree)
            if function_lines(f) > MAX_FUNCTION_LINES}
    new = {key: lines for key, lines in over.items() if key not in LONG_FUNCTIONS}
    assert not new, f'functions over {MAX_FUNCTION_LINES} lines without their docstring (split them): {new}'
    assert not LONG_FUNCTIONS - set(over), (
        f'no longer over {MAX_FUNCTION_LINES} lines, drop from LONG_FUNCTIONS: {sorted(LONG_FUNCTIONS - set(over))}')


def test_first_party_imports_are_at_the_top_of_modules():
    packages = set(_package_roots())
    inside = {}
    for path, _, tree in _sources():
        for f in _functions(tree):
            modules = first_party_imports_inside(f, packages)
            if modules:
                inside.setdefault(f'{path}:{f.name}', []).extend(modules)
    new = {key: modules for key, modules in inside.items() if key not in LAZY_IMPORTS}
    assert not new, f'first-party imports inside functions (move them to the top, or allowlist with why): {new}'
    assert not set(LAZY_IMPORTS) - set(inside), (
        f'no longer importing inside, drop from LAZY_IMPORTS: {sorted(set(LAZY_IMPORTS) - set(inside))}')
    assert all(LAZY_IMPORTS.values())


def test_no_private_name_is_imported_from_another_package():
    packages = set(_package_roots())
    found = {path: names for path, package, tree in _sources() if (names := private_imports(package, tree, packages))}
    new = {path: names - PRIVATE_IMPORTS.get(path, set()) for path, names in found.items()}
    new = {path: sorted(names) for path, names in new.items() if names}
    assert not new, f'private names imported from another package (make them public at home): {new}'
    gone = {path: sorted(names - found.get(path, set())) for path, names in PRIVATE_IMPORTS.items()
            if names - found.get(path, set())}
    assert not gone, f'no longer imported, drop from PRIVATE_IMPORTS: {gone}'
