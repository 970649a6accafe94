"""One error type for bad input at the boundary (CLI, YAML, CSV, ROS parameters), and the one check
of what a plain number is there (:func:`is_number`, :func:`is_whole`).

Its message is a single line that names the field and says how to fix it; the CLI prints
it without a traceback and exits with code 2.
"""

import math

import numpy as np


class ConfigError(ValueError):
    """Bad user input: the message names the offending field and the fix."""

    exit_code = 2

    def __init__(self, field: str, problem: str, fix: str = "", source: str = ""):
        where = f"{source}: " if source else ""
        tail = f"; {fix}" if fix else ""
        super().__init__(f"{where}{field}: {problem}{tail}")
        self.field, self.problem, self.fix, self.source = field, problem, fix, source

    def __reduce__(self):
        # Raised in worker processes (process pools, Dask) and sent back pickled: rebuilt from
        # its own fields (the default rebuilds from the message alone and fails).
        return type(self), (self.field, self.problem, self.fix, self.source)


def is_number(v, finite: bool = True) -> bool:
    """Whether ``v`` is a plain number as a file, the command line or a ROS parameter gives it: an
    int or a float (NumPy's too), not a bool (YAML's ``true`` is an int to Python), and finite
    unless ``finite=False`` (YAML reads ``.nan`` and ``.inf`` as floats). The one check of every
    reader of user input; each reader says what it expected in its own :class:`ConfigError`."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
        return False
    return not finite or math.isfinite(v)


def is_whole(v) -> bool:
    """Whether ``v`` is an integer as a file or a ROS parameter gives it: an int (NumPy's too), not
    a bool."""
    return not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, np.integer))
