"""The kernel modules register themselves where they live (uh_core.compiled_kernels, docs/performance.md#memory).

A package declares its kernel modules, the modules its kernels compile in and the kernels' builder
as entry points in its ``setup.py``; ``uh_core.compiled_kernels`` reads them and names no module of
a package above it. These tests check that the declarations, the installed entry points and the
code agree, and that the law's kernels index their arrays through the tables made from the gains'
and the status' registries (one declaration per gain or status field).
"""
import ast
import re
from pathlib import Path

import pytest

from uh_core import compiled_kernels, layout

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = sorted(d.name for d in ROOT.glob('uh_*') if (d / 'setup.py').is_file() and (d / d.name).is_dir())
GROUPS = (compiled_kernels.KERNEL_GROUP, compiled_kernels.KERNEL_INPUT_GROUP, compiled_kernels.KERNEL_BUILDER_GROUP)
#: The packages above uh_core (docs/architecture.md, tests/test_packaging.py::LAYERS).
ABOVE_UH_CORE = ('uh_topology', 'uh_wire', 'uh_sim_node', 'uh_controller_node', 'uh_team', 'uh_report',
                 'uh_campaign', 'uh_bringup', 'uh_security')


def _declared() -> dict:
    """``{group: {(package, name, value)}}`` of the entry points every ``setup.py`` declares."""
    found = {group: set() for group in GROUPS}
    for pkg in PACKAGES:
        for node in ast.walk(ast.parse((ROOT / pkg / 'setup.py').read_text())):
            if isinstance(node, ast.keyword) and node.arg == 'entry_points':
                for group, entries in ast.literal_eval(node.value).items():
                    for entry in entries if group in found else ():
                        name, _, value = (part.strip() for part in entry.partition('='))
                        found[group].add((pkg, name, value))
    return found


def _module_path(module: str) -> Path:
    """Return the file of a first-party module named ``module`` (``pkg.mod`` -> ``pkg/pkg/mod.py``)."""
    top, *rest = module.split('.')
    return ROOT / top / top / Path(*rest).with_suffix('.py')


def _modules():
    """``(dotted name, syntax tree)`` of every first-party module."""
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg / pkg).rglob('*.py')):
            parts = path.relative_to(ROOT / pkg).with_suffix('').parts
            yield '.'.join(parts[:-1] if parts[-1] == '__init__' else parts), ast.parse(path.read_text())


def test_every_declared_module_is_in_the_package_that_declares_it():
    declared = _declared()
    assert declared[compiled_kernels.KERNEL_GROUP] and declared[compiled_kernels.KERNEL_INPUT_GROUP]
    assert len(declared[compiled_kernels.KERNEL_BUILDER_GROUP]) == 1
    for group, entries in declared.items():
        for pkg, name, value in entries:
            module, _, function = value.partition(':')
            assert module.split('.')[0] == pkg, f'{pkg}/setup.py declares {module} of another package ({group})'
            path = _module_path(module)
            assert path.is_file(), f'{pkg}/setup.py: {group} {name} = {value}: no {path.relative_to(ROOT)}'
            if function:
                defined = {n.name for n in ast.parse(path.read_text()).body if isinstance(n, ast.FunctionDef)}
                assert function in defined, f'{pkg}/setup.py: {group} {name} = {value}: no function {function}'
            if group == compiled_kernels.KERNEL_GROUP:
                assert name.endswith('__'), f'{pkg}/setup.py: the prefix {name} of {module} ends in "__"'


def test_the_installed_entry_points_are_those_the_setup_files_declare():
    declared = _declared()
    kernels = {(module, kernel.prefix, kernel.warm_up) for module, kernel in compiled_kernels.kernel_modules().items()}
    expected = {(value.partition(':')[0], name, value.partition(':')[2])
                for _, name, value in declared[compiled_kernels.KERNEL_GROUP]}
    hint = 'the installed packages are older than their setup.py: source scripts/_venv.sh to reinstall them'
    assert kernels == expected, hint
    assert set(compiled_kernels.kernel_input_modules()) == \
        {value for _, _, value in declared[compiled_kernels.KERNEL_INPUT_GROUP]}, hint
    (builder,) = declared[compiled_kernels.KERNEL_BUILDER_GROUP]
    assert compiled_kernels.build_command() == f'python -m {builder[2].partition(":")[0]}', hint


def test_every_module_with_kernels_to_compile_is_declared_and_every_declared_one_has_kernels():
    installing, decorating = set(), set()
    for module, tree in _modules():
        if module == 'uh_core.compiled_kernels':
            continue
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == 'install'
                    and [ast.unparse(a) for a in node.args] == ['globals()']):
                installing.add(module)
            if isinstance(node, ast.ImportFrom) and node.module == 'uh_core.compiled_kernels' and \
                    any(alias.name == 'njit' for alias in node.names):
                decorating.add(module)
    declared = {value.partition(':')[0] for _, _, value in _declared()[compiled_kernels.KERNEL_GROUP]}
    assert installing == declared, (f'call compiled_kernels.install(globals()) but are not declared: '
                                    f'{sorted(installing - declared)}; declared but do not call it: '
                                    f'{sorted(declared - installing)}')
    assert decorating == declared, f'use compiled_kernels.njit without install, or the reverse: {decorating ^ declared}'


def test_no_declared_kernel_is_inlined():
    """numba.pycc's type inference failed on another kernel of the build when one kernel had inline='always'."""
    for _, _, value in _declared()[compiled_kernels.KERNEL_GROUP]:
        module = value.partition(':')[0]
        for node in ast.walk(ast.parse(_module_path(module).read_text())):
            if isinstance(node, ast.Call) and ast.unparse(node.func) == 'njit':
                assert 'inline' not in {k.arg for k in node.keywords}, f'{module}:{node.lineno}'


def test_no_kernel_input_is_a_kernel_module():
    inputs = {value for _, _, value in _declared()[compiled_kernels.KERNEL_INPUT_GROUP]}
    kernels = {value.partition(':')[0] for _, _, value in _declared()[compiled_kernels.KERNEL_GROUP]}
    assert not inputs & kernels


def test_uh_core_code_names_no_module_of_a_package_above_it():
    """No import, and no string but docstrings (a module named to import it, e.g. by importlib)."""
    above = re.compile(r'\b(' + '|'.join(ABOVE_UH_CORE) + r')\b')
    offenders = []
    for module, tree in _modules():
        if not module.startswith('uh_core'):
            continue
        docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                      if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                      and node.body and isinstance(node.body[0], ast.Expr)
                      and isinstance(node.body[0].value, ast.Constant)}
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
                names = [node.value]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or '']
            offenders += [f'{module}:{node.lineno}: {name!r}' for name in names if above.search(name)]
    assert not offenders


def test_the_compiled_module_name_follows_the_registry(monkeypatch):
    """A prefix or warm-up declared otherwise names other kernels: the digest changes, the old module is stale."""
    monkeypatch.setattr(compiled_kernels, '_digest_cache', [])
    before = compiled_kernels.library_name()
    kernels = dict(compiled_kernels.kernel_modules())
    module, kernel = next(iter(kernels.items()))
    kernels[module] = kernel._replace(prefix='renamed__')
    monkeypatch.setattr(compiled_kernels, 'kernel_modules', lambda: kernels)
    monkeypatch.setattr(compiled_kernels, '_digest_cache', [])
    assert compiled_kernels.library_name() != before


# -- the law's tables and the registries (one declaration per gain or status field) -------------------

LAW_KERNEL_MODULES = ('uh_controller_node.control_kernels', 'uh_controller_node.loop_kernels',
                      'uh_controller_node.learning_kernels')


def test_the_law_tables_are_made_from_the_registries():
    from uh_controller_node import control_layout as cl
    from uh_controller_node import gains
    assert cl.GAIN_ENTRIES == tuple(g.attr for g in gains.TOP_GAINS if g.slot)
    assert cl.LOOP_GAIN_ENTRIES == tuple(g.attr for g in gains.LOOP_GAINS if g.slot)
    field = {name: re.sub(r'\W', '_', name) for name in (*cl.MODEL_INDEX, *cl.GAIN_INDEX, *cl.LOOP_GAIN_OFFSET)}
    assert cl.PARAM._asdict() == {**{field[n]: i for n, i in {**cl.MODEL_INDEX, **cl.GAIN_INDEX}.items()},
                                  'outer': cl.PARAM.outer, 'inner': cl.PARAM.outer + cl.LOOP_GAINS_SIZE}
    assert cl.PARAM.outer == cl.GAIN_INDEX[cl.GAIN_ENTRIES[-1]] + 1
    assert cl.LOOP._asdict() == {field[n]: offset for n, offset in cl.LOOP_GAIN_OFFSET.items()}
    assert cl.STATUS._asdict() == layout.STATUS_INDEX
    assert all(type(value) is int for table in (cl.PARAM, cl.LOOP, cl.STATUS) for value in table)


@pytest.mark.parametrize('module', LAW_KERNEL_MODULES)
def test_the_law_kernels_index_their_arrays_through_the_tables(module):
    """Kernels read ``PARAM.x``, ``LOOP.x``, ``STATUS.x`` (each a name of its registry), no hand-made index."""
    from uh_controller_node import control_layout as cl
    tables = {'PARAM': set(cl.PARAM._fields), 'LOOP': set(cl.LOOP._fields), 'STATUS': set(cl.STATUS._fields)}
    tree = ast.parse(_module_path(module).read_text())
    kernels = [node for node in tree.body if isinstance(node, ast.FunctionDef)
               and any(ast.unparse(d).startswith('njit') for d in node.decorator_list)]
    assert kernels
    for kernel in kernels:
        for node in ast.walk(kernel):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in tables:
                assert node.attr in tables[node.value.id], f'{module}.{kernel.name}: {node.value.id}.{node.attr}'
            if isinstance(node, ast.Name):
                assert not re.match(r'(CP|L|S)_[A-Z]', node.id), f'{module}.{kernel.name} reads {node.id}'
