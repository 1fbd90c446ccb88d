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


class _Raised(Exception):
    pass


def _raise_on_signal(signum, frame):
    raise _Raised(f"signal {signum}")


@pytest.mark.skipif(not (os.name == "posix" and os.uname().sysname == "Linux"), reason="the child is forked on Linux")
def test_a_stopped_child_ends_by_the_signal_not_in_the_parents_handler(tmp_path, capfd):
    """The CLI's SIGTERM/SIGINT handlers raise; the child does not inherit them: cancel() ends it by the
    signal's default action, silently, instead of raising in the middle of whatever it was doing."""
    import signal

    old = {s: signal.signal(s, _raise_on_signal) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        job = ChildJob(_slow, tmp_path)
        time.sleep(0.5)
        job.cancel()
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    assert job._proc.exitcode == -signal.SIGTERM
    assert not (tmp_path / "late").exists()
    err = capfd.readouterr().err
    assert "Traceback" not in err and "_Raised" not in err
