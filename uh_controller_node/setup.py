"""Package setup of ``uh_controller_node`` (colcon and pip): the package and the ``controller_node`` executable."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'uh_controller_node'

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
    install_requires=['numpy', 'scipy', 'numba', 'PyYAML', 'uh_runtime', 'uh_core', 'uh_topology', 'uh_wire'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='Composite-learning inverse-optimal fault-tolerant formation-containment controller (per UH), its node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'controller_node = uh_controller_node.entry_points:controller_node',
        ],
        # the kernel modules (uh_core.compiled_kernels): prefix in the compiled module = module:warm-up
        # (the module alone: its kernels are compiled by the warm-up of the kernels that call them)
        'uh_kernels': [
            'control__ = uh_controller_node.control_kernels:compile_control_kernels',
            'loops__ = uh_controller_node.loop_kernels',
            'learning__ = uh_controller_node.learning_kernels',
            'isolation__ = uh_controller_node.isolation_kernels:compile_isolation_kernels',
            'impairments__ = uh_controller_node.impairments:compile_impairment_kernels',
            'safety__ = uh_controller_node.safety_kernels:compile_safety_kernels',
        ],
        # what the kernels compile in without being kernel modules: the layout of the law's arrays, the gains' slots
        'uh_kernel_inputs': [
            'control_layout = uh_controller_node.control_layout',
            'gains = uh_controller_node.gains',
        ],
    },
)
