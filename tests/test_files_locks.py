"""Locks on the resolved path, a commit that is all or nothing, and exit codes that tell the truth after a signal.

Signals are delivered from inside the tool at a chosen point (``signal.raise_signal`` from a
patched file operation), so each case is deterministic rather than a race against a timer.
"""

from __future__ import annotations

import errno
import os
import re
import signal
from pathlib import Path

import pytest
from typer.testing import CliRunner

from commission.infra import files
from commission.cli.main import app, run
from commission.errors import OutputError, UsageError
from commission.infra.files import Outputs

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data" / "axis_excitation.h5"
runner = CliRunner()
NAMES = ("a.json", "b.json", "c.json")


def listing(d: Path) -> dict[str, bytes]:
    """Every file under ``d`` (hidden ones included) with its bytes."""
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def leftovers(*folders: Path) -> list[str]:
    return [p.name for d in folders if d.exists() for p in d.iterdir()
            if ".tmp-" in p.name or ".old-" in p.name or p.name.endswith(".lock")]


def old_set(d: Path) -> dict[str, bytes]:
    d.mkdir(parents=True, exist_ok=True)
    for n in NAMES:
        (d / n).write_text(f"old {n}\n")
    return listing(d)


def write_set(o: Outputs, d: Path, names=NAMES) -> None:
    for n in names:
        o.path(d / n).write_text(f"new {n}\n")


# --------------------------------------------------------------------------- one lock per folder


def _spellings(tmp_path: Path, monkeypatch) -> list[Path]:
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "link").symlink_to(real)
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    return [tmp_path / "link", tmp_path / "sub" / ".." / "real", Path("real"), Path("./link/")]


def test_every_spelling_of_a_folder_is_the_same_lock(tmp_path, monkeypatch):
    spellings = _spellings(tmp_path, monkeypatch)
    held = Outputs(force=True)
    held.add_dir(tmp_path / "real", NAMES, "--out-dir")
    with held:
        for s in spellings:
            o = Outputs(force=True)
            o.add_dir(s, NAMES, "--out-dir")
            with pytest.raises(UsageError, match=r"^--out-dir .*: in use by another commission process \(pid "
                                                 rf"{os.getpid()}, "):
                o.open()
        write_set(held, tmp_path / "real")
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == sorted(NAMES)
    assert leftovers(tmp_path, tmp_path / "real") == []


def test_a_run_through_a_symlinked_out_dir_is_refused_while_another_holds_the_folder(tmp_path, monkeypatch):
    # The case: the second command must not replace the first's set; it is refused
    # before any computation, naming the holder.
    _spellings(tmp_path, monkeypatch)
    held = Outputs(force=False)
    held.add_dir(tmp_path / "real", ("ident.json",), "--out-dir")
    with held:
        r = runner.invoke(app, ["run", str(SAMPLE), "--out-dir", str(tmp_path / "link")])
        assert r.exit_code == 2, r.output
        assert re.fullmatch(r"error: --out-dir \S+/link: in use by another commission process \(pid \d+, .*\); "
                            r"wait for it or choose another output\n", r.stderr), r.stderr
        write_set(held, tmp_path / "real", ("ident.json",))
    assert (tmp_path / "real" / "ident.json").read_text() == "new ident.json\n"


def test_a_file_written_through_a_symlink_lands_in_the_file_it_points_to(tmp_path):
    real = tmp_path / "d" / "real.json"
    real.parent.mkdir()
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    o = Outputs(force=True)
    o.add_file(link, "--out")
    with o:
        staged = o.path(link)
        staged.write_text("new")
    assert link.is_symlink() and real.read_text() == "new"
    assert o.final(staged) == link  # what the user typed, for the "wrote" line
    assert leftovers(tmp_path, real.parent) == []


def test_two_targets_that_are_one_place_are_refused(tmp_path):
    (tmp_path / "link").symlink_to(tmp_path)
    o = Outputs(force=True)
    o.add_file(tmp_path / "x.json", "--out")
    with pytest.raises(UsageError, match=r"--plot .*: the same place as --out"):
        o.add_file(tmp_path / "link" / "x.json", "--plot")


def test_an_output_that_is_a_dangling_symlink_is_refused_by_name(tmp_path):
    (tmp_path / "gone").symlink_to(tmp_path / "missing")
    o = Outputs(force=True)
    with pytest.raises(UsageError, match=r"^--out-dir \S+/gone: a symlink to \S+/missing, which does not exist"):
        o.add_dir(tmp_path / "gone", NAMES, "--out-dir")
    with pytest.raises(UsageError, match=r"^--out \S+/gone: a symlink to \S+/missing, which does not exist"):
        o.add_file(tmp_path / "gone", "--out")
    assert os.listdir(tmp_path) == ["gone"]


def test_an_existing_folder_under_an_unwritable_parent_is_locked_inside(tmp_path, monkeypatch):
    # --out-dir . in a home folder whose parent is read-only: the lock and staging go inside it,
    # and every process that may write it (in place, necessarily) takes that lock.
    out = tmp_path / "home"
    before = old_set(out)
    real_access, parent = os.access, Path(os.path.realpath(tmp_path))
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == parent else real_access(p, mode, **kw))
    monkeypatch.chdir(out)
    held = Outputs(force=True)
    held.add_dir(".", NAMES, "--out-dir")
    with held:
        assert [p.name for p in tmp_path.iterdir()] == ["home"]  # nothing beside it
        assert ".home.lock" in os.listdir(out)
        o = Outputs(force=True)
        o.add_dir(out, NAMES, "--out-dir")
        with pytest.raises(UsageError, match="in use by another commission process"):
            o.open()
        write_set(held, Path("."))
    assert listing(out) == {n: f"new {n}\n".encode() for n in NAMES} != before


# --------------------------------------------------------------------------- all or nothing


def _failing_rename(monkeypatch, fail_at: int, err=errno.ENOSPC):
    real = os.rename
    calls = []

    def rename(src, dst, *a, **kw):
        calls.append(dst)
        if len(calls) == fail_at:
            raise OSError(err, os.strerror(err), str(dst))
        return real(src, dst, *a, **kw)

    monkeypatch.setattr(os, "rename", rename)
    return calls


@pytest.mark.parametrize("fail_at", [1, 2, 3])
def test_a_full_disk_during_the_commit_puts_the_old_set_back(tmp_path, monkeypatch, fail_at):
    out = tmp_path / "out"
    old_set(out)
    o = Outputs(force=True)
    o.add_dir(out, (*NAMES, "d.json"), "--out-dir")
    (out / "d.json").write_text("an output this run does not produce\n")
    before = listing(out)
    with o:
        write_set(o, out)
        _failing_rename(monkeypatch, fail_at)
        with pytest.raises(OutputError, match=r"^--out-dir \S+/out: cannot move the outputs into place \(No space "
                                              r"left on device\); nothing written or replaced$"):
            o.commit()
    assert listing(out) == before
    assert leftovers(tmp_path, out) == [] and not o.committed


def test_a_full_disk_while_writing_is_one_error_and_leaves_nothing(tmp_path):
    out = tmp_path / "out"
    o = Outputs(force=False)
    o.add_dir(out, NAMES, "--out-dir")
    with pytest.raises(OutputError, match=r"^--out-dir \S+/out: cannot write \(No space left on device\); "
                                          r"nothing written or replaced$"):
        with o:
            o.path(out / "a.json").write_text("half")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert list(tmp_path.iterdir()) == []


def test_an_error_reading_an_input_is_not_taken_for_a_write_error(tmp_path):
    o = Outputs(force=False)
    o.add_dir(tmp_path / "out", NAMES, "--out-dir")
    with pytest.raises(OSError) as info:
        with o:
            raise OSError(errno.EIO, "Input/output error", str(tmp_path / "log.h5"))
    assert not isinstance(info.value, OutputError)
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- signals at the final move


def _signal_during_commit(monkeypatch, sig: int, at: int = 1):
    """Deliver ``sig`` to this process from inside the ``at``-th rename of a commit."""
    real = os.rename
    n = [0]

    def rename(src, dst, *a, **kw):
        n[0] += 1
        if n[0] == at:
            signal.raise_signal(sig)
        return real(src, dst, *a, **kw)

    monkeypatch.setattr(os, "rename", rename)


@pytest.fixture()
def python_sigint():
    """Python's own SIGINT handler for the test, whatever this process inherited: a job that a
    non-interactive shell starts in the background begins with SIGINT ignored, and Python keeps it so."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize("existing", [False, True])
def test_a_signal_during_the_commit_is_acted_on_once_the_set_is_in_place(tmp_path, monkeypatch, existing,
                                                                        python_sigint):
    # Library semantics: the interrupt is raised after the commit, which completed.
    out = tmp_path / "out"
    if existing:
        old_set(out)
    files.forget_commits()
    o = Outputs(force=True)
    o.add_dir(out, NAMES, "--out-dir")
    with pytest.raises(KeyboardInterrupt):
        with o:
            write_set(o, out)
            _signal_during_commit(monkeypatch, signal.SIGINT, at=2 if existing else 1)
    assert o.committed and files.committed_outputs() == (out,)
    assert listing(out) == {n: f"new {n}\n".encode() for n in NAMES}
    assert leftovers(tmp_path, out) == []


def _identify(tmp_path, *extra):
    return ["identify", str(SAMPLE), "--out", str(tmp_path / "out" / "ident.json"), *extra]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_cli_a_signal_during_the_final_move_exits_0_with_the_set_in_place(tmp_path, monkeypatch, capfd, sig):
    real_commit = Outputs.commit

    def commit(self):
        _signal_during_commit(monkeypatch, sig)
        real_commit(self)

    monkeypatch.setattr(Outputs, "commit", commit)
    code = run(_identify(tmp_path))
    err = capfd.readouterr().err
    assert code == 0, err
    assert (tmp_path / "out" / "ident.json").is_file()
    assert err.strip().splitlines()[-1] == (f"{'terminated' if sig == signal.SIGTERM else 'interrupted'} after the "
                                            "outputs were complete: kept them (exit 0)")
    assert leftovers(tmp_path, tmp_path / "out") == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_cli_a_signal_before_the_final_move_exits_128_plus_sig_with_nothing_in_place(tmp_path, monkeypatch, capfd,
                                                                                      sig):
    import commission.cli.identify_cmd as cmd

    real_write = cmd.write_json_atomic

    def write(path, obj, **kw):  # the staged file is complete, the move not started
        real_write(path, obj, **kw)
        signal.raise_signal(sig)

    monkeypatch.setattr(cmd, "write_json_atomic", write)
    code = run(_identify(tmp_path))
    err = capfd.readouterr().err
    assert code == 128 + sig, err
    word = "terminated" if sig == signal.SIGTERM else "interrupted"
    assert err.strip().splitlines()[-1] == f"{word}: no output written or replaced"
    assert list(tmp_path.iterdir()) == []  # not even the folder --out would have created


def test_cli_an_interrupt_that_skips_the_with_blocks_cleanup_still_leaves_nothing(tmp_path, monkeypatch, capfd):
    # An interrupt landing in ``__exit__`` before the commit holds signals: the CLI's net aborts.
    def commit(self):
        raise KeyboardInterrupt

    mine = Outputs(force=False)  # the caller's own, open before the command: not the command's to abort
    mine.add_dir(tmp_path / "mine", NAMES, "--out-dir")
    mine.open()
    monkeypatch.setattr(Outputs, "commit", commit)
    monkeypatch.setattr(Outputs, "__exit__", lambda self, *exc: self.commit())
    code = run(_identify(tmp_path))
    assert code == 130, capfd.readouterr().err
    assert sorted(n[:9] for n in leftovers(tmp_path)) == [".mine.loc", ".mine.tmp"]  # still open
    assert not (tmp_path / "out").exists()
    monkeypatch.undo()
    write_set(mine, tmp_path / "mine")
    mine.commit()
    assert sorted(os.listdir(tmp_path)) == ["mine"]


def test_cli_a_full_disk_is_one_line_exit_2_and_nothing_written(tmp_path, monkeypatch, capfd):
    out = tmp_path / "out"
    out.mkdir()
    (out / "ident.json").write_text("the old one\n")
    real_commit = Outputs.commit

    def commit(self):
        _failing_rename(monkeypatch, 1)
        real_commit(self)

    monkeypatch.setattr(Outputs, "commit", commit)
    code = run(_identify(tmp_path, "--force"))
    err = capfd.readouterr().err
    assert code == 2, err
    assert re.fullmatch(r"error: --out \S+/ident.json: cannot move the outputs into place \(No space left on "
                        r"device\); nothing written or replaced\n", err), err
    assert listing(out) == {"ident.json": b"the old one\n"}
    assert leftovers(tmp_path, out) == []


def test_cli_a_write_error_outside_outputs_is_one_line_too(tmp_path, monkeypatch):
    import commission.cli.identify_cmd as cmd

    def full(paths):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "somewhere"))

    monkeypatch.setattr(cmd, "expand_log_paths", full)
    r = runner.invoke(app, _identify(tmp_path))
    assert r.exit_code == 2
    assert r.stderr == f"error: {tmp_path / 'somewhere'}: cannot write (No space left on device)\n"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("when", ["atexit", "teardown"])
def test_console_script_a_signal_as_the_process_shuts_down_keeps_the_exit_code(tmp_path, sig, when):
    # After its outputs are in place the process still runs the atexit functions and, in a plain
    # interpreter exit, a slow module teardown with the default signal action back in place.
    import subprocess
    import sys

    out = tmp_path / "ident.json"
    script = f"""
import os, sys
sys.argv = ["commission", "identify", {str(SAMPLE)!r}, "--out", {str(out)!r}]
from commission.cli import main as m

class Late:
    def __del__(self):
        os.kill(os.getpid(), {int(sig)})

if {when!r} == "atexit":
    import atexit
    atexit.register(lambda: os.kill(os.getpid(), {int(sig)}))
else:
    m.late_probe = Late()  # dropped when the modules are torn down
m.main()
"""
    # run outside the checkout: `python -c` puts the current folder first on sys.path, and the
    # source folder commission/ there is not the installed package (commission.cli lives in cli/)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert p.returncode == 0, (p.returncode, p.stderr)
    assert out.is_file() and "Traceback" not in p.stderr
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_cli_a_signal_wrapped_by_python_while_a_class_is_created_is_still_the_signal(tmp_path, monkeypatch, capfd,
                                                                                    sig):
    # A signal landing in a dataclass's __set_name__ during an import comes out as a RuntimeError whose
    # cause is the signal's exception: it is the signal (exit 128 + sig, nothing written), not a crash.
    import dataclasses

    import commission.cli.identify_cmd as cmd

    def write(path, obj, **kw):
        class Field:
            def __set_name__(self, owner, name):
                signal.raise_signal(sig)

        dataclasses.dataclass(type("Late", (), {"f": Field()}))

    monkeypatch.setattr(cmd, "write_json_atomic", write)
    code = run(_identify(tmp_path))
    err = capfd.readouterr().err
    assert code == 128 + sig, err
    word = "terminated" if sig == signal.SIGTERM else "interrupted"
    assert err.strip().splitlines()[-1] == f"{word}: no output written or replaced" and "internal error" not in err
    assert list(tmp_path.iterdir()) == []
