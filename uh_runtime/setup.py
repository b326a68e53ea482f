"""Package setup of ``uh_runtime`` (colcon and pip): the package, ``uh``, the recorder, live-view and replay nodes."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'uh_runtime'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob(package_name + '/config/*.yaml')),
    ],
    package_data={package_name: ['config/*.yaml']},
    install_requires=['numpy', 'PyYAML', 'rosbags', 'mcap', 'mcap-ros2-support', 'threadpoolctl'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description=('Node runtime of the UH stack: an rclpy-shaped node facade with an rclpy backend and a Cyclone DDS '
                 'backend that follows ROS 2 wire conventions; the uh inspection CLI; the MCAP recorder and player.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'uh = uh_runtime.cli.uh:main',
            'recorder_node = uh_runtime.bags.recorder:main',
            'live_view_node = uh_runtime.bags.live_view:main',
            'replay_node = uh_runtime.bags.replay:main',
        ],
    },
)
