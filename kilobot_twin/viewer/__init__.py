"""Viewing recordings: bags and batch results -> arrays (:mod:`.swarm_data`) -> Rerun (:mod:`.rerun_view`).

``swarm_data`` is NumPy only; ``bag_source`` reads bags (rclpy deserialisation); ``rerun_view``
is the only module that imports ``rerun``.
"""

from __future__ import annotations

from pathlib import Path


def load_source(source: str | Path, point: int = 0, run: int = 0):
    """A bag directory or a batch results ``.npz`` -> :class:`~.swarm_data.SwarmRecording`."""
    from ..errors import ConfigError

    src = Path(source)
    if src.suffix == ".npz":
        from .swarm_data import from_results

        return from_results(src, point=point, run=run)
    if src.is_dir():
        from .bag_source import from_bag

        return from_bag(src)
    raise ConfigError(str(src), "not a bag directory or a results .npz",
                      "give bags/NAME (from `run` or `import`) or results.npz (from `simulate`)")
