"""The repository is a set of real ROS 2 Jazzy packages (DESIGN.md section 1)."""
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

ROOT = Path(__file__).resolve().parents[1]
PYTHON_PACKAGES = ['uh_runtime', 'uh_topology', 'uh_sim_node', 'uh_controller_node', 'uh_bringup']
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
    for name in sorted(files):
        text = (ROOT / 'uh_msgs' / 'msg' / f'{name}.msg').read_text()
        types = get_types_from_msg(text, f'uh_msgs/msg/{name}')
        store.register(types)
        assert store.hash_rihs01(f'uh_msgs/msg/{name}').startswith('RIHS01_')
