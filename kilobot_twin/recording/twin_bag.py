"""Write twin-shaped bags without a running graph (imports, test fixtures, benchmarks).

:class:`TwinBagWriter` puts robot samples, ``/clock``, traits and world documents on the same
topics, types and QoS strings a recording of the live twin has, serialised by :mod:`.cdr`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from .bag import BagWriter
from .cdr import clock_cdr, image_cdr, robot_cdr, string_cdr
from .topics import DATA_QOS, LATCHED_QOS, ROBOT_TYPES as TYPES, robot_namespace


class TwinBagWriter:
    """A :class:`BagWriter` with the twin's topics registered on first use."""

    def __init__(self, path: str | Path, **kwargs):
        self.bag = BagWriter(path, **kwargs)
        self._cid: dict[str, int] = {}

    def channel(self, topic: str, type_name: str, latched: bool = False) -> int:
        cid = self._cid.get(topic)
        if cid is None:
            cid = self._cid[topic] = self.bag.add_topic(topic, type_name, LATCHED_QOS if latched else DATA_QOS)
        return cid

    def robot_sample(self, robot_id: int, stamp_ns: int, log_ns: int, x_m: float | None = None,
                     y_m: float | None = None, theta_rad: float | None = None, reading: float | None = None,
                     led: int | None = None) -> None:
        """One robot's messages at one time; ``None`` leaves that topic out (not measured / a gap).

        Written in the live robot's order (light, led, then pose) with the same log time.
        """
        (pose,), (light,), (colour,), _clock = robot_cdr(int(stamp_ns), x_m or 0.0, y_m or 0.0, theta_rad or 0.0,
                                                          reading or 0.0, 0.0, 2 if led is None else int(led), 0.0, 1.0)
        ns = robot_namespace(robot_id)
        if reading is not None and math.isfinite(reading):
            self.bag.write(self.channel(f"{ns}/light", TYPES["light"]), light, log_ns)
        if led is not None:
            self.bag.write(self.channel(f"{ns}/led", TYPES["led"]), colour, log_ns)
        if x_m is not None and y_m is not None and math.isfinite(x_m) and math.isfinite(y_m):
            self.bag.write(self.channel(f"{ns}/pose", TYPES["pose"]), pose, log_ns)

    def clock(self, stamp_ns: int, log_ns: int) -> None:
        self.bag.write(self.channel("/clock", "rosgraph_msgs/msg/Clock"), clock_cdr(stamp_ns), log_ns)

    def document(self, topic: str, doc, log_ns: int, latched: bool = True) -> None:
        """A std_msgs/String JSON document (traits, scenario, state)."""
        text = doc if isinstance(doc, str) else json.dumps(doc, sort_keys=True)
        self.bag.write(self.channel(topic, TYPES["traits"], latched=latched), string_cdr(text), log_ns)

    def light_field(self, intensity, stamp_ns: int, log_ns: int) -> None:
        self.bag.write(self.channel("/world/light_field", "sensor_msgs/msg/Image", latched=True),
                       image_cdr(intensity, stamp_ns), log_ns)

    def close(self, custom_data: dict | None = None) -> Path:
        return self.bag.close(custom_data)
