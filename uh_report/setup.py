"""Package setup of ``uh_report`` (colcon and pip): the package and the ``uh-report`` console script."""
from setuptools import find_packages, setup

package_name = 'uh_report'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['numpy', 'scipy', 'matplotlib', 'rosbags', 'uh_core', 'uh_runtime', 'uh_topology', 'uh_wire', 'uh_controller_node', 'uh_team'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='Reports of UH formation runs and campaigns: metrics from a recorded bag, statistics, figures and the Markdown/HTML report (uh-report).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'uh-report = uh_report.report:main',
        ],
    },
)
