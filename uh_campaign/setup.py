"""Package setup of ``uh_campaign`` (colcon and pip): the package and the ``uh-campaign`` console script."""
from setuptools import find_packages, setup

package_name = 'uh_campaign'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['numpy', 'PyYAML', 'uh_runtime', 'uh_core', 'uh_topology', 'uh_controller_node', 'uh_team', 'uh_report'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='Monte Carlo campaigns of in-process UH team runs: the campaign spec (YAML), its per-run draws, the resumable runner (local processes or a Dask cluster) and uh-campaign.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'uh-campaign = uh_campaign.cli:main',
        ],
    },
)
