"""Package setup of ``uh_core`` (colcon and pip): the package and its config (``helicopter.yaml``, the airframe)."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'uh_core'

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
    install_requires=['numpy', 'numba', 'PyYAML'],
    zip_safe=True,
    maintainer='UH formation maintainers',
    maintainer_email='maintainers@uh-formation.invalid',
    description='What the simulator and the controller of the UH formation-containment stack share, free of any middleware: state, input and reference layouts, airframe parameters, records, frames and health windows.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
        ],
        # what the compiled kernels are made from besides the kernel modules (uh_core.compiled_kernels)
        'uh_kernel_inputs': [
            'layout = uh_core.layout',
        ],
    },
)
