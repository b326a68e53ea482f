"""Package setup of ``uh_security`` (colcon and pip): the package and the ``uh-security`` console script."""
from setuptools import find_packages, setup

package_name = 'uh_security'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['cryptography', 'uh_runtime', 'uh_topology', 'uh_wire', 'uh_bringup'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='Secure mode of a UH team: the DDS Security access-control policy generated from the scenario\'s communication graph and the topic registry, and uh-security, which writes it with a CA, one identity per node and signed governance and permissions as an sros2 keystore.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'uh-security = uh_security.cli:main',
        ],
    },
)
