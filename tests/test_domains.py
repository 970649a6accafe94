"""The ROS domains the test workers take (tests/conftest.py): checked by enumeration."""

import os

from .conftest import DOMAINS_PER_BAND, own_domain, worker_domain


def test_workers_of_one_run_never_share_a_domain_and_every_band_stays_in_fast_dds_range():
    for workers in (1, 2, 3, 4, 8, 16, 76):
        for run in ("a", "9f1c2e", "12345", "gw-run-x"):
            doms = [worker_domain(run, i, workers) for i in range(workers)]
            assert len(set(doms)) == workers, (run, workers, doms)
            for d in doms:
                assert 1 <= d <= DOMAINS_PER_BAND  # never 0, ROS's default
                assert d + 2 * DOMAINS_PER_BAND <= 232  # Fast DDS: "Calculated port number is too high" above


def test_two_runs_take_the_same_slot_or_disjoint_domains():
    """Two runs at once (two checkouts, CI beside a developer) never half-overlap: either their
    ids fall in one slot (1 in 38 for two workers: the same as two single runs' pids) or none of
    their workers' domains meet."""
    for workers in (2, 3, 8):
        sets = [frozenset(worker_domain(f"run{r}", i, workers) for i in range(workers)) for r in range(200)]
        for a in sets:
            for b in sets:
                assert a == b or not a & b, (workers, sorted(a), sorted(b))


def test_this_process_took_its_domain_and_its_bands_differ():
    d = int(os.environ["ROS_DOMAIN_ID"])
    assert 1 <= d <= DOMAINS_PER_BAND
    assert len({d, int(own_domain(1)), int(own_domain(2))}) == 3
