"""Package setup of ``uh_wire`` (colcon and pip): the package; it has no console scripts."""
from setuptools import find_packages, setup

package_name = 'uh_wire'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['numpy', 'uh_runtime', 'uh_core', 'uh_topology'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='What a UH node puts on and takes off the ROS graph: the registry of topic names, types and QoS, conversions between the core arrays and uh_msgs messages, the standard views (tf, odometry, diagnostics) and the run parameters every node declares.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
        ],
    },
)
