import os
import zlib

# Every test process gets its own ROS domain and stays on localhost (see README). The suite runs
# on pytest-xdist workers (`make test`: -n auto): the workers of one run share
# PYTEST_XDIST_TESTRUNUID and differ in their index, so they take neighbouring domains of one slot
# and never hear each other; separate runs take slots by that id (or by the pid, without xdist).
# Domains 1-76 only: tests that need a second or third domain of their own add 76 or 152
# (:func:`own_domain`), and Fast DDS's ports overflow above 232. Domain 0, ROS's default, is left
# to the user's robots.
DOMAINS_PER_BAND = 76


def worker_domain(run: str, index: int, workers: int) -> int:
    """The domain of worker ``index`` of ``workers`` in the test run named ``run``."""
    workers = max(int(workers), 1)
    slots = max(DOMAINS_PER_BAND // workers, 1)
    return 1 + ((zlib.crc32(run.encode()) % slots) * workers + int(index) % workers) % DOMAINS_PER_BAND


os.environ["ROS_DOMAIN_ID"] = str(worker_domain(os.environ.get("PYTEST_XDIST_TESTRUNUID") or str(os.getpid()),
                                                int(os.environ.get("PYTEST_XDIST_WORKER", "gw0")[2:] or 0),
                                                int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def own_domain(band: int) -> str:
    """A DDS domain for this test process alone in ``band`` 1 or 2 (its domain + 76 * band): for
    tests whose nodes must not meet those of an earlier test in the same process."""
    return str(int(os.environ["ROS_DOMAIN_ID"]) + DOMAINS_PER_BAND * band)
