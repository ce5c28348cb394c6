"""ament_python setup for flow_node: `colcon build` installs the executables to lib/flow_node."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "flow_node"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/config", ["config/flow_node.policy.xml"]),  # SROS2 policy (docs/security.md)
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools", "numpy", "opencv-python-headless", "PyYAML"],
    extras_require={"fast": ["numba"], "bag": ["rosbags"]},
    zip_safe=True,
    maintainer="flow_node maintainers",
    maintainer_email="flow_node@example.com",
    description="Variational dense optical flow for ROS 2 (primal-dual, coarse-to-fine).",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "flow_node = flow_node.ros.node:main",
            "flow_estimate = flow_node.cli.estimate:main",
            "flow_bag = flow_node.bag.cli:main",
            "flow_node_policy = flow_node.ros.security_policy:main",
        ],
    },
)
