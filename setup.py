"""ament_python package ``ost_ros``: the Object-Sorting Task core, messages and ROS 2 nodes.

Installable with pip (``bringup_scripts/setup.sh``) or built by colcon on a full ROS 2 install,
where ``ros2 run ost_ros world_node`` / ``ros2 run ost_ros agent_node`` work.
"""

from setuptools import find_packages, setup

package_name = "ost_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(
        include=[
            "ost_ros",
            "ost_ros.*",
            "ost_msgs_py",
            "ost_msgs_py.*",
            "world_node",
            "world_node.*",
            "agent_node",
            "agent_node.*",
        ]
    ),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", ["launch/team.launch.py"]),
    ],
    install_requires=["setuptools", "numpy", "PyYAML", "cryptography", "PyNaCl"],
    # Studies on a Dask cluster (``--cluster``; imported only then). requirements.lock pins them.
    extras_require={"cluster": ["dask", "distributed"]},
    python_requires=">=3.12",
    zip_safe=True,
    maintainer="OST project",
    maintainer_email="ost@example.invalid",
    description="Object-Sorting Task: cost-balanced (CCP) and help-based (HCP) cooperation, node per robot",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ost = ost_ros.cli:main",
            "world_node = world_node.world_node:main",
            "agent_node = agent_node.agent_node:main",
            "watch_node = world_node.watch_node:main",
        ],
    },
)
