"""The bag writer as the recorder node imports it; bags live in :mod:`kilobot_twin.recording.bag`."""

from ..recording.bag import DEFAULT_CHUNK_BYTES, BagWriter  # noqa: F401
from ..recording.topics import qos_yaml  # noqa: F401
