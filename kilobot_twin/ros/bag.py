"""Bag names as the recorder node and the launcher import them; bags live in
:mod:`kilobot_twin.recording.bag`."""

from ..recording.bag import DEFAULT_CHUNK_BYTES, BagWriter, summary_counts  # noqa: F401
from ..recording.topics import qos_yaml  # noqa: F401
