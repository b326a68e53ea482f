"""Package setup of ``uh_team`` (colcon and pip): the package and the ``uh-simulate`` console script."""
from setuptools import find_packages, setup

package_name = 'uh_team'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['numpy', 'scipy', 'numba', 'PyYAML', 'uh_runtime', 'uh_core', 'uh_topology', 'uh_sim_node', 'uh_controller_node'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='The whole UH team in one process: in-process reference simulation on the team kernel, metrics of a run, uh-simulate.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'uh-simulate = uh_team.simulate_cli:main',
            'uh-analyze = uh_team.analyze_cli:main',
        ],
        # python -m of this module builds the compiled kernels (uh_core.compiled_kernels)
        'uh_kernel_builder': [
            'compile_kernels = uh_team.compile_kernels:main',
        ],
    },
)
