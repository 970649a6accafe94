"""Where a verb may write: checks of an output path before anything is created.

Every verb that writes checks its output with one of these functions before it computes or
starts anything, so that a careless ``--out`` ends with one line (exit code 2) and leaves
nothing behind. :class:`CreatedDirs` removes folders a failed verb created and left empty.
Nothing here deletes a file.
"""

from __future__ import annotations

from pathlib import Path

from .errors import ConfigError


def _parents_are_folders(p: Path, field: str) -> None:
    for a in p.parents:
        if a.exists():
            if not a.is_dir():
                raise ConfigError(field, f"{a} is a file, not a folder", "choose a path under a folder")
            return


def _holds_recording(p: Path) -> str | None:
    """What user data a folder holds: a bag (metadata.yaml / *.mcap), a dataset (meta.yaml), or None."""
    if (p / "metadata.yaml").is_file() or any(p.glob("*.mcap")):
        return "a bag"
    if (p / "meta.yaml").is_file():
        return "a measured dataset"
    return None


def check_out_file(path: str | Path, field: str = "--out") -> Path:
    """An output file: not an existing folder, under folders (not files)."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError(field, f"{path} is a folder", "give a file path, e.g. results/NAME.npz")
    _parents_are_folders(p, field)
    return p


def check_out_dir(path: str | Path, field: str = "--out", new: bool = False) -> Path:
    """An output folder: not a file, under folders, never a folder that holds a bag or a dataset.

    ``new``: the folder must not exist yet or be empty (for verbs whose output is user data,
    e.g. a dataset, that a second run must not silently overwrite).
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ConfigError(field, f"{path} is a file", "give a folder path")
    _parents_are_folders(p, field)
    if p.is_dir():
        held = _holds_recording(p)
        if held:
            raise ConfigError(field, f"{path} already holds {held}", "choose a new folder; nothing overwrites recorded data")
        if new and any(p.iterdir()):
            raise ConfigError(field, f"{path} already exists and is not empty", "choose a new folder name")
    return p


class CreatedDirs:
    """Remember which of some paths (and their parents) do not exist yet; :meth:`remove_empty`
    removes those that a failed verb then created and left empty (deepest first)."""

    def __init__(self, *paths):
        self.missing: list[Path] = []
        for path in paths:
            if not path:
                continue
            p = Path(path).absolute()
            for a in (p, *p.parents):
                if a.exists():
                    break
                self.missing.append(a)
        self.missing.sort(key=lambda a: len(a.parts), reverse=True)

    def remove_empty(self) -> None:
        for a in self.missing:
            try:
                if a.is_dir() and not a.is_symlink() and not any(a.iterdir()):
                    a.rmdir()
            except OSError:
                pass
