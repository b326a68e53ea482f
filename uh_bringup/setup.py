"""Package setup of ``uh_bringup`` (colcon and pip): the launch files and ``uh-run-formation``, ``uh-inject-fault``."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'uh_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['numpy', 'PyYAML', 'rosbags', 'uh_runtime', 'uh_core', 'uh_topology', 'uh_wire', 'uh_sim_node',
                      'uh_controller_node', 'uh_team', 'uh_report'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='Bring-up of a UH formation-containment run: the table of a team\'s nodes, the launch file, '
                'the run supervisor behind scripts/run_formation.sh (one process per node, recording, metrics '
                'from the bag), composition, network namespaces and fault injection.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'uh-run-formation = uh_bringup.run_formation:main',
            'uh-inject-fault = uh_bringup.inject_fault:main',
        ],
    },
)
