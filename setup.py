"""ament_python package ``ost_ros``: the Object-Sorting Task core, messages and ROS 2 nodes.

Installable with pip (``bringup_scripts/setup.sh``) or built by colcon beside ``ost_msgs``
(``colcon build --base-paths . ost_msgs_py/ost_msgs``), after which ``ros2 run ost_ros agent_node``
and ``ros2 launch ost_ros team.launch.py`` work (docs/development.md, "Interfaces").
"""

from glob import glob

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
    # What ros2 run / ros2 launch look for under the install prefix (colcon; pip's editable
    # install skips data_files, so bringup_scripts/setup.sh links the same into the venv).
    # The Fast DDS profiles every process of a run loads (ost_ros/commands/bringup.py).
    package_data={"ost_ros": ["dds/*.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", sorted(glob("launch/*.launch.py"))),
    ],
    # Every third-party library the product imports, by its PyPI name (tests/test_packaging.py
    # checks it against the imports); the exact versions are requirements.lock's. The ROS side
    # (rclpy, the message packages, ost_msgs, launch) is package.xml's: it comes from the ROS
    # install — or the pinned ros-* wheels of requirements.lock — and ost_msgs is on no index.
    install_requires=[
        "numpy>=1.26",
        "scipy",
        "PyYAML",
        "shapely>=2.0",  # the vectorised module-level functions
        "matplotlib",
        "pillow",
        "tqdm",
        "cryptography",
        "mcap",
        "foxglove-sdk",
        "imageio-ffmpeg",
    ],
    # Studies on a Dask cluster (``--cluster``; imported only then). requirements.lock pins them.
    extras_require={"cluster": ["dask", "distributed"]},
    python_requires=">=3.12",
    zip_safe=True,
    maintainer="OST project",
    maintainer_email="ost@example.invalid",
    description=(
        "Object-Sorting Task, one ROS 2 process per robot: cooperation protocols (CCP, HCP and "
        "the others of `ost protocols list`), negotiation between robots, the papers' studies"
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ost = ost_ros.cli:main",
            "world_node = world_node.world_node:main",
            "membership_node = world_node.membership:main",
            "agent_node = agent_node.agent_node:main",
            "watch_node = world_node.watch_node:main",
        ],
    },
)
