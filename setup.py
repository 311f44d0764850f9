"""ament_python build script for inertia_ros.

colcon (``colcon build``) and pip both use this file.  The data files below put the package
marker into the ament index and the parameter files, scenes and sample logs under
``share/inertia_ros`` where ``ros2 run`` / ``ros2 launch`` users expect them.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'inertia_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/scenes', glob('config/scenes/*.yaml')),
        ('share/' + package_name + '/bags', glob('bags/*.mcap') + glob('bags/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='inertia_ros maintainers',
    maintainer_email='maintainers@users.noreply.h-seed-a8376161.example',
    description='Rigid-body inertia tensor estimation from gyro and torque streams (ROS 2 Jazzy).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            # Executables are registered here as the issue that builds each one lands.
            'inertia_estimator = inertia_ros.inertia_estimator_node:main',
            'scene_simulator = inertia_ros.scene_simulator_node:main',
            'bag_player = inertia_ros.bag_player_node:main',
        ],
    },
)
