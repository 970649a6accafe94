"""A ConfigError raised in a worker process reaches the parent whole (process pools and Dask
send exceptions back pickled)."""

import pickle
from concurrent.futures import ProcessPoolExecutor

import pytest

from kilobot_twin.errors import ConfigError


def _raise():
    raise ConfigError("robots", "must be positive, got 0", "e.g. --robots 10", source="run.yaml")


def test_config_error_survives_a_process_pool():
    err = ConfigError("robots", "must be positive, got 0", "e.g. --robots 10", source="run.yaml")
    back = pickle.loads(pickle.dumps(err))
    assert str(back) == str(err) == "run.yaml: robots: must be positive, got 0; e.g. --robots 10"
    assert back.field == "robots"
    with ProcessPoolExecutor(1) as pool, pytest.raises(ConfigError, match="robots: must be positive"):
        pool.submit(_raise).result()
