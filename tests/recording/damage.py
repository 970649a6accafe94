"""Damaged copies of a good bag (fixed seeds): the kinds a user meets after a crash or a bad disk."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np


def _copy(good: Path, dst: Path) -> Path:
    """``dst`` as a bag directory holding ``good``'s files under its own name."""
    dst.mkdir(parents=True)
    shutil.copy(good / "metadata.yaml", dst / "metadata.yaml")
    shutil.copy(good / f"{good.name}_0.mcap", dst / f"{dst.name}_0.mcap")
    return dst / f"{dst.name}_0.mcap"


def truncate(good: Path, dst: Path, seed: int) -> Path:
    f = _copy(good, dst)
    data = f.read_bytes()
    cut = int(np.random.default_rng(seed).integers(16, len(data) - 1))
    f.write_bytes(data[:cut])
    return dst


def flip(good: Path, dst: Path, seed: int, n: int = 50) -> Path:
    f = _copy(good, dst)
    data = bytearray(f.read_bytes())
    rng = np.random.default_rng(seed)
    for k in rng.choice(len(data), size=n, replace=False):
        data[k] ^= 1 << int(rng.integers(8))
    f.write_bytes(bytes(data))
    return dst


def zero_block(good: Path, dst: Path, seed: int, size: int = 4096) -> Path:
    f = _copy(good, dst)
    data = bytearray(f.read_bytes())
    at = int(np.random.default_rng(seed).integers(0, len(data) - size))
    data[at:at + size] = bytes(size)
    f.write_bytes(bytes(data))
    return dst


def random_bytes(good: Path, dst: Path, seed: int) -> Path:
    f = _copy(good, dst)
    f.write_bytes(np.random.default_rng(seed).bytes(f.stat().st_size))
    return dst


def unfinalised(good: Path, dst: Path, seed: int) -> Path:
    """As after SIGKILL: the data section only (no summary, footer, metadata.yaml), cut inside a record."""
    from kilobot_twin.recording.bag import BagReader

    f = _copy(good, dst)
    (dst / "metadata.yaml").unlink()
    data = f.read_bytes()
    end = BagReader(good, warn=False).data_end_offset
    f.write_bytes(data[:int(np.random.default_rng(seed).integers(len(data) // 3, end))])
    return dst


KINDS = {"truncated": truncate, "flipped": flip, "zeroed": zero_block, "random": random_bytes,
         "unfinalised": unfinalised}
