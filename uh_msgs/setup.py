"""pip path only: installs the .msg files to <prefix>/share/uh_msgs/msg.

A ROS 2 install keeps them there too, so the Cyclone DDS backend of uh_runtime builds its message
classes from the same files. colcon ignores this file: package.xml declares ament_cmake, and rosidl
generates the code.
"""
from pathlib import Path

from setuptools import setup

here = Path(__file__).parent
setup(
    name='uh_msgs',
    version='0.1.0',
    description='uh_msgs message definitions (.msg files) for the non-ROS (Cyclone DDS) path',
    packages=[],
    data_files=[('share/uh_msgs/msg', sorted(str(p.relative_to(here)) for p in (here / 'msg').glob('*.msg'))),
                ('share/uh_msgs', ['package.xml'])],
)
