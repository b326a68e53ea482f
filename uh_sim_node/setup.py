"""Package setup of ``uh_sim_node`` (colcon and pip): the sim, virtual-leader, sensing, lockstep-clock and view nodes."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'uh_sim_node'

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
    install_requires=['numpy', 'numba', 'PyYAML', 'uh_runtime', 'uh_core', 'uh_wire', 'uh_topology'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='Unmanned-helicopter dynamics with actuator faults, the per-UH simulator node, the virtual-leader node and the lockstep clock.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_node = uh_sim_node.entry_points:sim_node',
            'virtual_leader_node = uh_sim_node.virtual_leader_node:main',
            'lockstep_clock_node = uh_sim_node.clock_node:main',
            'visualization_node = uh_sim_node.visualization_node:main',
            'sensing_node = uh_sim_node.sensing_node:main',
        ],
        # the kernel modules (uh_core.compiled_kernels): prefix in the compiled module = module:warm-up
        'uh_kernels': [
            'plant__ = uh_sim_node.plant_kernels:compile_plant_kernels',
        ],
    },
)
