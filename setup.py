from glob import glob

from setuptools import find_packages, setup

PACKAGE = "kilobot_twin"

setup(
    name=PACKAGE,
    version="0.1.0",
    description="A digital twin of a Kilobot swarm of individuals (ROS 2 Jazzy, NumPy, MCAP, Rerun)",
    license="MIT",
    python_requires=">=3.10",
    packages=find_packages(exclude=["tests", "tests.*", "benchmarks"]),
    package_data={PACKAGE: ["ros/fastdds.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/msg_schemas", glob("msg_schemas/*.msg")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    # Compatible ranges for `pip install .`; requirements.txt pins the exact versions `make` uses.
    install_requires=[
        "setuptools",
        "ros-jazzy-rclpy[fastrtps]>=7.1.6,<8",
        "ros-jazzy-common-interfaces>=5.3.6,<6",
        "numpy>=1.26,<3",
        "mcap>=1.2,<2",
        "zstandard>=0.22",
        "rerun-sdk>=0.41,<0.42",
        "pyyaml>=6",
        "tqdm>=4.60",
        "matplotlib>=3.8",
        "scipy>=1.11",
        "pyarrow>=14",
        "numba>=0.63",
        "dask[distributed]>=2024.8",
    ],
    zip_safe=False,
    entry_points={
        "console_scripts": [
            "kilobot-twin = kilobot_twin.cli:main",
            "robot = kilobot_twin.nodes.robot:main",
            "swarm = kilobot_twin.nodes.swarm:main",
            "world = kilobot_twin.nodes.world:main",
            "analysis = kilobot_twin.nodes.analysis:main",
            "recorder = kilobot_twin.nodes.recorder:main",
            "replay = kilobot_twin.nodes.replay:main",
        ],
    },
)
