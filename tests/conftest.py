import os
import zlib

# Every test process gets its own ROS domain and stays on localhost (see README). The suite runs
# on two pytest-xdist workers (`make test`): the workers of one run share PYTEST_XDIST_TESTRUNUID
# and differ in their index, so they take neighbouring domains of one slot and never hear each
# other; separate runs take slots by that id (or by the pid, without xdist). Domains 1-76 only:
# tests that need a second or third domain of their own add 76 or 152 (:func:`own_domain`), and
# Fast DDS's ports overflow above 232. Domain 0, ROS's default, is left to the user's robots.
DOMAINS_PER_BAND = 76
_workers = max(int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")), 1)
_index = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0")[2:] or 0) % _workers
_run = os.environ.get("PYTEST_XDIST_TESTRUNUID") or str(os.getpid())
_slots = max(DOMAINS_PER_BAND // _workers, 1)
os.environ["ROS_DOMAIN_ID"] = str(1 + (zlib.crc32(_run.encode()) % _slots) * _workers + _index)
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def own_domain(band: int) -> str:
    """A DDS domain for this test process alone in ``band`` 1 or 2 (its domain + 76 * band): for
    tests whose nodes must not meet those of an earlier test in the same process."""
    return str(int(os.environ["ROS_DOMAIN_ID"]) + DOMAINS_PER_BAND * band)
