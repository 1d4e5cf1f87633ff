"""Launch the slip estimator with the package's default parameters.

``ros2 launch slip_estimator slip_estimator.launch.py params_file:=/path/to/params.yaml``
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory('slip_estimator'), 'config',
                                  'slip_estimator.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=default_params),
        Node(package='slip_estimator', executable='slip_estimator_node', name='slip_estimator',
             parameters=[LaunchConfiguration('params_file')], output='screen'),
    ])
