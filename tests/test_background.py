"""commission.infra.background.ChildJob: the writer's result and errors come back to the parent."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from commission.infra.background import ChildJob
from commission.errors import DataError


def _write(folder: Path, name: str) -> list[Path]:
    p = folder / name
    p.write_text(str(os.getpid()))
    return [p]


def _fail(message: str) -> None:
    raise DataError(message)


def _slow(folder: Path) -> None:
    time.sleep(30)
    (folder / "late").write_text("x")


def test_the_result_and_the_files_of_the_writer_reach_the_parent(tmp_path):
    job = ChildJob(_write, tmp_path, "fig.png")
    paths = job.result()
    assert paths == [tmp_path / "fig.png"] and paths[0].exists()
    if os.name == "posix" and os.uname().sysname == "Linux":  # forked: another process wrote it
        assert int(paths[0].read_text()) != os.getpid()


def test_an_error_in_the_writer_is_raised_in_the_parent_with_its_type_and_text(tmp_path):
    job = ChildJob(_fail, "figure: bad sample 12")
    with pytest.raises(DataError, match="figure: bad sample 12"):
        job.result()


def test_a_cancelled_job_writes_nothing_more(tmp_path):
    job = ChildJob(_slow, tmp_path)
    job.cancel()
    time.sleep(0.2)
    assert not (tmp_path / "late").exists()
