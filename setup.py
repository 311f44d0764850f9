"""ament_python build script for inertia_ros.

colcon (``colcon build``) and pip both use this file.  The data files below put the package
marker into the ament index and the parameter files, scenes, launch files, RViz/Foxglove
configurations and sample logs under ``share/inertia_ros`` where ``ros2 run`` / ``ros2 launch``
users expect them.  The ``test`` extra makes ``colcon test`` run the suite with pytest (without
it colcon falls back to unittest and finds nothing).
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
        ('share/' + package_name, ['package.xml', 'LICENSE']),
        ('share/' + package_name + '/launch', glob('launch/*.launch.xml')),
        ('share/' + package_name + '/config',
         glob('config/*.yaml') + glob('config/*.rviz') + glob('config/*.json')),
        ('share/' + package_name + '/config/scenes', glob('config/scenes/*.yaml')),
        ('share/' + package_name + '/config/wheels', glob('config/wheels/*.yaml')),
        ('share/' + package_name + '/config/rotors', glob('config/rotors/*.yaml')),
        ('share/' + package_name + '/bags', glob('bags/*.mcap') + glob('bags/*.yaml')),
    ],
    install_requires=['setuptools'],
    # Test tools, as pip names (the pins are in requirements-test.txt; rosdep keys in
    # package.xml).  colcon picks pytest as the test runner from this extra.
    extras_require={
        'test': ['pytest', 'pytest-timeout', 'hypothesis', 'catkin-pkg', 'rosbags',
                 'mcap-ros2-support', 'ruff', 'urdfdom-py'],
    },
    zip_safe=True,
    maintainer='inertia_ros maintainers',
    maintainer_email='inertia-ros@users.noreply.github.com',
    description='Rigid-body inertia tensor estimation from gyro and torque streams (ROS 2 Jazzy).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            # ROS 2 nodes (ros2 run inertia_ros NAME)
            'inertia_estimator = inertia_ros.inertia_estimator_node:main',
            'scene_simulator = inertia_ros.scene_simulator_node:main',
            'bag_player = inertia_ros.bag_player_node:main',
            'exciter = inertia_ros.exciter_node:main',
            # The offline command line (python -m inertia_ros): estimate, simulate, bench, demo
            'inertia-ros = inertia_ros.cli:main',
        ],
    },
)
