"""One error type for bad input at the boundary (CLI, YAML, CSV, ROS parameters).

Its message is a single line that names the field and says how to fix it; the CLI prints
it without a traceback and exits with code 2.
"""


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
