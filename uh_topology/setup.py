"""Package setup of ``uh_topology`` (colcon and pip): the package and its config (scenarios, gains, campaigns)."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'uh_topology'

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
    install_requires=['numpy', 'PyYAML', 'scipy', 'uh_core'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='The team of the UH formation-containment stack: scenario loading and validation, the communication graph and its Laplacian maths, generated teams.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [

        ],
    },
)
