"""Dask schedulers for campaigns: ``local:N`` (a LocalCluster of N processes) or ``tcp://HOST:PORT``.

A campaign's tasks are independent (random streams are keyed by seed, run and robot), so any
scheduler that runs them gives the same arrays. One client per scheduler string is kept for
the life of the process, so a command that runs several campaigns (``reproduce``) starts a
local cluster once; :func:`close_all` (also run at exit) shuts them down.
"""

from __future__ import annotations

import atexit
import logging
import re

from ..errors import ConfigError

_TCP = re.compile(r"^tcp://[A-Za-z0-9._\-\[\]:]+:\d{1,5}$")
_FIX = "use local:N (N worker processes on this machine) or tcp://HOST:PORT (a running dask scheduler)"
_CLIENTS: dict[str, object] = {}


def parse_scheduler(spec: str) -> tuple[str, int | str]:
    """``("local", N)`` or ``("tcp", address)``; a one-line :class:`ConfigError` otherwise."""
    text = str(spec).strip()
    if text.startswith("local:"):
        n = text[len("local:"):]
        if not n.isdigit() or int(n) < 1:
            raise ConfigError("scheduler", f"{text!r}: N in local:N must be a positive integer", _FIX)
        return "local", int(n)
    if _TCP.match(text):
        return "tcp", text
    raise ConfigError("scheduler", f"{text!r} is not a scheduler address", _FIX)


def client(spec: str):
    """A connected ``distributed.Client`` for ``spec`` (started or reused)."""
    kind, value = parse_scheduler(spec)
    c = _CLIENTS.get(spec)
    if c is not None and getattr(c, "status", "") == "running":
        return c
    try:
        import distributed
    except ImportError:  # pragma: no cover - a dependency
        raise ConfigError("scheduler", "dask.distributed is not installed", "pip install 'dask[distributed]'") from None
    if kind == "local":
        cluster = distributed.LocalCluster(n_workers=value, threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=logging.ERROR)
        c = distributed.Client(cluster)
    else:
        try:
            c = distributed.Client(value, timeout="5s")
        except (OSError, TimeoutError) as exc:
            raise ConfigError("scheduler", f"no Dask scheduler answers at {value} ({type(exc).__name__})",
                              "start one (dask scheduler / dask-jobqueue, see README) or check host and port") from None
    _CLIENTS[spec] = c
    return c


def worker_threads(c) -> int:
    """Threads over all workers of a client's cluster (at least 1)."""
    return max(1, sum(c.nthreads().values()))


def close_all() -> None:
    """Close every client this process opened (and the local clusters it started)."""
    while _CLIENTS:
        _, c = _CLIENTS.popitem()
        cluster = getattr(c, "cluster", None)
        try:
            c.close()
            if cluster is not None:
                cluster.close()
        except Exception:  # pragma: no cover - best effort at shutdown
            pass


atexit.register(close_all)
