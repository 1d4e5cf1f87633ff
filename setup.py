"""ament_python packaging; also installs with plain pip for development and CI."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'slip_estimator'
ROS_WHEELS = ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-sensor-msgs', 'ros-jazzy-nav-msgs',
              'ros-jazzy-geometry-msgs', 'ros-jazzy-diagnostic-msgs', 'ros-jazzy-std-msgs',
              'ros-jazzy-std-srvs']

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.py')),
    ],
    # The core needs numpy; the node and the offline tools need rclpy and the ROS message
    # packages: from ROS (apt, colcon) or, for a plain pip install, the ros-jazzy-* wheels
    # (extra "ros"; requirements.txt); replay, simulate, evaluate and demo read and write bags
    # with rosbags and parameter files with YAML. Extras for one tool each: import-pathfinder
    # (h5py), evaluate's figures and validate (matplotlib).
    install_requires=['setuptools', 'numpy>=1.24', 'pyyaml', 'rosbags>=0.10'],
    extras_require={'pathfinder': ['h5py'], 'plots': ['matplotlib'],
                    'ros': ROS_WHEELS, 'test': ['pytest', 'hypothesis']},
    zip_safe=True,
    maintainer='slip_estimator developers',
    maintainer_email='slip-estimator@example.org',
    description='Proprioceptive wheel-slip estimation for planetary rovers (INS + error-state EKF).',
    license='MIT',
    entry_points={
        'console_scripts': [
            # `ros2 run slip_estimator slip_estimator_node` and the plain console script.
            'slip_estimator_node = slip_estimator.ros.node:main',
            'slip-estimator-node = slip_estimator.ros.node:main',
            'slip-estimator = slip_estimator.cli:main',
        ],
    },
)
