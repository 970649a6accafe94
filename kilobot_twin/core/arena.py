"""The arena (open or walled) and the coverage grid for "non-overlapping area covered"."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .constants import BODY_RADIUS_M


@dataclass(frozen=True)
class Arena:
    """A square-ish arena centred on the origin.

    ``walls=False``: open plane (the size only frames plots and fields). ``walls=True``: the
    robot's body cannot cross the walls; a robot driving into one slides along it (its
    position is clamped, its heading is kept), a simple stand-in for the physics engine.
    ``coverage_cell_m`` is the side of the coverage grid's square cells.
    """

    width_m: float = 4.0
    height_m: float = 4.0
    walls: bool = False
    coverage_cell_m: float = 0.02

    def confine(self, x, y):
        if not self.walls:
            return x, y
        hx = 0.5 * self.width_m - BODY_RADIUS_M
        hy = 0.5 * self.height_m - BODY_RADIUS_M
        return np.clip(x, -hx, hx), np.clip(y, -hy, hy)

    @property
    def grid_shape(self) -> tuple[int, int]:
        return (int(np.ceil(self.width_m / self.coverage_cell_m)), int(np.ceil(self.height_m / self.coverage_cell_m)))

    def cell_index(self, x, y):
        """Flat coverage-cell index of each position (clipped to the grid)."""
        nx, ny = self.grid_shape
        ix = np.clip(((np.asarray(x) + 0.5 * self.width_m) / self.coverage_cell_m).astype(np.int64), 0, nx - 1)
        iy = np.clip(((np.asarray(y) + 0.5 * self.height_m) / self.coverage_cell_m).astype(np.int64), 0, ny - 1)
        return ix * ny + iy


class Coverage:
    """Which grid cells each (run, robot) has visited; memory ``prod(shape) * cells`` bytes."""

    def __init__(self, arena: Arena, shape):
        self.arena = arena
        nx, ny = arena.grid_shape
        self.cells = nx * ny
        self.visited = np.zeros((int(np.prod(shape, dtype=np.int64)), self.cells), dtype=bool)
        self._rows = np.arange(self.visited.shape[0])
        self.shape = tuple(shape)

    def mark(self, x, y):
        idx = self.arena.cell_index(x, y).reshape(-1)
        self.visited[self._rows, idx] = True

    def area_m2(self):
        return (self.visited.sum(axis=1) * self.arena.coverage_cell_m**2).reshape(self.shape)
