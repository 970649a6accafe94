import os

import pytest

# Every test process gets its own ROS domain and stays on localhost (see README).
os.environ.setdefault("ROS_DOMAIN_ID", str(100 + os.getpid() % 100))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def pytest_collection_modifyitems(config, items):
    if config.getoption("-m") and "slow" in config.getoption("-m"):
        return
    if os.environ.get("KILOBOT_SLOW") == "1":
        return
    skip = pytest.mark.skip(reason="slow Monte Carlo check: run with `make test-slow`")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
