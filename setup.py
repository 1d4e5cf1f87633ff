"""ament_python packaging; also installs with plain pip for development and CI."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'slip_estimator'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.py')),
    ],
    package_data={package_name: ['data/*.yaml']},
    install_requires=['setuptools', 'numpy'],
    zip_safe=True,
    maintainer='slip_estimator developers',
    maintainer_email='slip-estimator@example.org',
    description='Proprioceptive wheel-slip estimation for planetary rovers (INS + error-state EKF).',
    license='MIT',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            # `ros2 run slip_estimator slip_estimator_node` and the plain console script.
            'slip_estimator_node = slip_estimator.ros.node:main',
            'slip-estimator-node = slip_estimator.ros.node:main',
            'slip-estimator = slip_estimator.cli:main',
        ],
    },
)
