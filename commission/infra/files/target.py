"""One declared output (a file or a folder) and the state of its lock, staging and backup."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Target:
    """One output of :class:`commission.infra.files.Outputs`: where it goes, and what this run holds for it."""

    dest: Path          # the output file, or the output folder, as the user spelled it
    names: tuple[str, ...]  # files of a folder target; (dest.name,) for a file target
    is_dir: bool
    flag: str
    real: Path = Path()  # dest with every symlink, ``..`` and ``.`` resolved: where the files go
    lock_fd: int | None = None
    lock_path: Path | None = None
    staging: Path | None = None
    staged_at: Path | None = None  # the staging folder, remembered after commit for final()
    backup: Path | None = None  # the replaced files during commit (same folder: renames only)
    moved_whole: bool = False  # the staging folder itself became the output folder
    made_dirs: list[Path] = field(default_factory=list)

    @property
    def folder(self) -> Path:
        return self.real if self.is_dir else self.real.parent

    def final(self, name: str) -> Path:
        """Where the staged file ``name`` goes."""
        return self.real / name if self.is_dir else self.real


def resolved(p: Path) -> Path:
    """``p`` with every symlink, ``..`` and ``.`` resolved (parts that do not exist yet kept as written)."""
    return Path(os.path.realpath(p))
