"""The repository is a set of real ROS 2 Jazzy packages whose dependencies run one way (docs/architecture.md)."""
import ast
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

ROOT = Path(__file__).resolve().parents[1]
PYTHON_PACKAGES = ['uh_runtime', 'uh_core', 'uh_topology', 'uh_wire', 'uh_sim_node', 'uh_controller_node', 'uh_team',
                   'uh_report', 'uh_campaign', 'uh_bringup', 'uh_security']
ALL_PACKAGES = ['uh_msgs', *PYTHON_PACKAGES]


@pytest.mark.parametrize('pkg', ALL_PACKAGES)
def test_package_xml_is_format_3_with_matching_name(pkg):
    root = ET.parse(ROOT / pkg / 'package.xml').getroot()
    assert root.tag == 'package' and root.get('format') == '3'
    assert root.findtext('name') == pkg
    build_type = root.find('export/build_type').text
    assert build_type == ('ament_cmake' if pkg == 'uh_msgs' else 'ament_python')


@pytest.mark.parametrize('pkg', PYTHON_PACKAGES)
def test_ament_python_layout(pkg):
    assert (ROOT / pkg / 'resource' / pkg).is_file()
    assert (ROOT / pkg / pkg / '__init__.py').is_file()
    cfg = (ROOT / pkg / 'setup.cfg').read_text()
    assert f'$base/lib/{pkg}' in cfg  # where `ros2 run` looks for the entry points


def test_colcon_workspace_points_at_every_package():
    for pkg in ALL_PACKAGES:
        link = ROOT / 'ros2_ws' / 'src' / pkg
        assert link.is_symlink() and link.resolve() == (ROOT / pkg).resolve()


def test_every_msg_is_generated_and_parses():
    cmake = (ROOT / 'uh_msgs' / 'CMakeLists.txt').read_text()
    listed = set(re.findall(r'"msg/(\w+)\.msg"', cmake))
    files = {p.stem for p in (ROOT / 'uh_msgs' / 'msg').glob('*.msg')}
    assert listed == files and files
    store = get_typestore(Stores.ROS2_JAZZY)
    for name in sorted(files):   # all first: a type may hold another uh_msgs type (ReceivedStates)
        text = (ROOT / 'uh_msgs' / 'msg' / f'{name}.msg').read_text()
        store.register(get_types_from_msg(text, f'uh_msgs/msg/{name}'))
    for name in sorted(files):
        assert store.hash_rihs01(f'uh_msgs/msg/{name}').startswith('RIHS01_')


#: the layers of docs/architecture.md, lowest first: a package may depend only on lower layers
LAYERS = [['uh_msgs'], ['uh_runtime'], ['uh_core'], ['uh_topology'], ['uh_wire'], ['uh_sim_node', 'uh_controller_node'],
          ['uh_team'], ['uh_report'], ['uh_campaign'], ['uh_bringup'], ['uh_security']]
LAYER_OF = {pkg: n for n, layer in enumerate(LAYERS) for pkg in layer}


def _first_party_depends(pkg):
    root = ET.parse(ROOT / pkg / 'package.xml').getroot()
    return {e.text for e in root.iter() if e.tag.endswith('depend') and e.text in LAYER_OF}


def _imported_packages(pkg):
    """First-party packages imported anywhere in ``pkg``'s modules (module level or in functions)."""
    found = {}
    for path in sorted((ROOT / pkg / pkg).rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            for name in names:
                top = name.split('.')[0]
                if top in LAYER_OF and top != pkg:
                    found.setdefault(top, f'{path.relative_to(ROOT)}:{node.lineno}')
    return found


def test_every_package_is_in_a_layer():
    assert set(ALL_PACKAGES) == set(LAYER_OF)


@pytest.mark.parametrize('pkg', PYTHON_PACKAGES)
def test_dependencies_run_one_way(pkg):
    """Each package.xml names only lower layers, and the code imports only what package.xml names.

    The simulator and the controller never import each other; only uh_security, above it, imports uh_bringup.
    """
    depends = _first_party_depends(pkg)
    upward = sorted(d for d in depends if LAYER_OF[d] >= LAYER_OF[pkg])
    assert not upward, f'{pkg}/package.xml depends on {upward}, which are not below it'
    undeclared = {top: where for top, where in _imported_packages(pkg).items() if top not in depends}
    assert not undeclared, f'{pkg} imports packages its package.xml does not declare: {undeclared}'


@pytest.mark.parametrize('pkg', PYTHON_PACKAGES)
def test_setup_py_declares_the_package_xml_dependencies(pkg):
    setup = (ROOT / pkg / 'setup.py').read_text()
    required = set(re.findall(r"'(uh_\w+)'", setup[setup.index('install_requires'):]))
    assert _first_party_depends(pkg) - {'uh_msgs'} <= required


#: third-party module -> the rosdep key a package importing it must declare (rosdistro's
#: rosdep/python.yaml; keys ending in -pip install from PyPI on a ROS machine). cyclonedds is the
#: DDS backend's alone, which a ROS machine does not use (it runs on rclpy), so it has no key; nor
#: has foxglove (the live view of the pip-only path: a ROS machine runs foxglove_bridge).
ROSDEP_KEYS = {'numpy': 'python3-numpy', 'numba': 'python3-numba', 'yaml': 'python3-yaml',
               'scipy': 'python3-scipy', 'matplotlib': 'python3-matplotlib',
               'rosbags': 'python3-rosbags-pip', 'mcap': 'mcap-ros2-support',
               'mcap_ros2': 'mcap-ros2-support', 'cryptography': 'python3-cryptography'}


@pytest.mark.parametrize('pkg', PYTHON_PACKAGES)
def test_third_party_imports_are_declared_as_rosdep_keys(pkg):
    root = ET.parse(ROOT / pkg / 'package.xml').getroot()
    declared = {e.text for e in root.iter() if e.tag.endswith('depend')}
    missing = {}
    for path in sorted((ROOT / pkg / pkg).rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
            for name in names:
                key = ROSDEP_KEYS.get(name.split('.')[0])
                if key and key not in declared:
                    missing.setdefault(key, f'{path.relative_to(ROOT)}:{node.lineno}')
    assert not missing, f'{pkg}/package.xml lacks exec_depend {missing}'


def _pins(path):
    pins = {}
    for line in (ROOT / path).read_text().splitlines():
        line = line.split('#')[0].strip()
        if line:
            name, _, version = line.partition('==')
            pins[name.lower()] = version
    return pins


def test_the_ros_machine_requirements_agree_with_the_pinned_ones_and_keep_numpy_1():
    main, ros, constraints = (_pins('requirements.txt'), _pins('requirements-ros.txt'),
                              _pins('constraints-ros-jazzy.txt'))
    assert all(version for version in ros.values()), 'every ROS-machine requirement is pinned'
    for name in set(main) & set(ros) - {'numba'}:     # numba: the release that supports numpy 1.26
        assert ros[name] == main[name], name
    assert 'numpy' not in ros and constraints['numpy'].startswith('1.26.')
    assert {'rosbags', 'mcap', 'mcap-ros2-support', 'numba'} <= set(ros)


#: rosdep keys whose package the ROS machine takes from requirements-ros.txt instead (docs/ros2.md): Ubuntu
#: 24.04 has no python3-numba, and rosdep's pip keys install unpinned as root
FROM_REQUIREMENTS_ROS = {'python3-numba': 'numba', 'python3-rosbags-pip': 'rosbags',
                         'mcap-ros2-support': 'mcap-ros2-support'}


def test_the_documented_ros_install_skips_exactly_the_keys_requirements_ros_provides():
    doc = (ROOT / 'docs' / 'ros2.md').read_text()
    block = doc[doc.index('## Installing'):]
    block = block[block.index('```bash'):block.index('```', block.index('```bash') + 7)]
    skipped = set(re.search(r'--skip-keys "([^"]+)"', block).group(1).split())
    declared = {e.text for pkg in PYTHON_PACKAGES for e in ET.parse(ROOT / pkg / 'package.xml').getroot().iter()
                if e.tag.endswith('depend')}
    assert skipped == set(FROM_REQUIREMENTS_ROS) and skipped <= declared
    assert {FROM_REQUIREMENTS_ROS[k] for k in skipped} <= set(_pins('requirements-ros.txt'))
    # PEP 668: Ubuntu 24.04 refuses a pip install into the user site without it
    pip_line = next(line for line in block.splitlines() if line.startswith('pip install'))
    assert '--break-system-packages' in pip_line and '-c constraints-ros-jazzy.txt' in pip_line
    assert '--break-system-packages' in (ROOT / 'requirements-ros.txt').read_text().split('\n\n')[0]


#: ROS packages imported by module name that follow no naming pattern (message packages end in _msgs or
#: _interfaces, or are named by a type string 'pkg/msg/Name')
ROS_MODULES = {'rclpy', 'launch', 'launch_ros', 'ament_index_python', 'rmw_dds_common', 'builtin_interfaces',
               'rosidl_runtime_py', 'tf2_ros', 'rosbag2_py'}
TYPE_NAME = re.compile(r"""['"]([a-z][a-z0-9_]*)/(?:msg|srv|action)/[A-Z]\w*['"]""")


def _ros_packages_used(path):
    """``{ROS package: line}`` that the module ``path`` imports or names a message or service type of."""
    used = {}
    text = path.read_text()
    for node in ast.walk(ast.parse(text, str(path))):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
            [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
        for name in names:
            top = name.split('.')[0]
            if top in ROS_MODULES or top.endswith(('_msgs', '_interfaces')):
                used.setdefault(top, node.lineno)
    for match in TYPE_NAME.finditer(text):
        used.setdefault(match.group(1), text.count('\n', 0, match.start()) + 1)
    return used


@pytest.mark.parametrize('pkg', PYTHON_PACKAGES)
def test_every_ros_package_the_code_uses_is_declared_in_package_xml(pkg):
    """A ROS package the code imports or names a type of ('nav_msgs/msg/Odometry') is in package.xml.

    rosdep installs, and colcon orders the build by, package.xml alone: an undeclared message package
    makes a fresh ROS 2 install fail at run time.
    """
    root = ET.parse(ROOT / pkg / 'package.xml').getroot()
    declared = {e.text for e in root.iter() if e.tag.endswith('depend')}
    missing = {}
    for path in sorted((ROOT / pkg / pkg).rglob('*.py')):
        for used, line in _ros_packages_used(path).items():
            if used not in declared and used not in (pkg, 'pkg'):   # 'pkg/msg/Type': a docstring's placeholder
                missing.setdefault(used, f'{path.relative_to(ROOT)}:{line}')
    assert not missing, f'{pkg}/package.xml lacks exec_depend {missing}'


def test_the_ros_package_check_sees_imports_and_type_names(tmp_path):
    module = tmp_path / 'm.py'
    module.write_text("import rclpy.node\nfrom tf2_msgs.msg import TFMessage\nimport numpy\n"
                      "ODOM = 'nav_msgs/msg/Odometry'\nX = 'not/a/type'\n")
    assert _ros_packages_used(module) == {'rclpy': 1, 'tf2_msgs': 2, 'nav_msgs': 4}


def _console_scripts(pkg):
    """Return ``[(executable, 'module:function')]`` of ``pkg``'s setup.py."""
    for node in ast.walk(ast.parse((ROOT / pkg / 'setup.py').read_text())):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values, strict=True):
                if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                    return [tuple(part.strip() for part in ast.literal_eval(e).split('=')) for e in value.elts]
    return []


@pytest.mark.parametrize('pkg', PYTHON_PACKAGES)
def test_every_console_script_names_a_function_of_its_package(pkg):
    for executable, target in _console_scripts(pkg):
        module, _, function = target.partition(':')
        assert module.split('.')[0] == pkg, f'{executable} = {target}'
        path = ROOT / pkg / Path(*module.split('.'))
        source = path.with_suffix('.py') if path.with_suffix('.py').is_file() else path / '__init__.py'
        assert source.is_file(), f'{executable} = {target}: no module {module}'
        tree = ast.parse(source.read_text(), str(source))
        assert function in {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}, f'{executable} = {target}'
