"""Entry point of the ``commission`` console script.

Start-up is kept light: this module imports typer and nothing numeric.  Each
command's module (and with it numpy, scipy, numba, h5py, matplotlib) is
imported only when that command runs or its own help is asked for
(:class:`LazyGroup`), so that ``commission --help`` answers at once
(``benchmarks/bench_cli_help.py``).

:func:`main` is the one place that decides how the process ends (CONTRACT §4):

* ``0`` success, ``1`` a validation gate failed, ``2`` bad input or usage:
  one line on stderr naming the file, field or flag
  (:func:`commission.cli.errors.cli_errors` for the tool's own errors, a
  one-line rendering of click's usage errors here);
* anything unexpected is a bug: one line on stderr saying so, with the path
  of a log file that holds the traceback, and exit ``2``; never a traceback
  on stderr (``--verbose`` adds it);
* Ctrl-C exits ``130`` and SIGTERM ``143`` (128 + the signal) with one line,
  at any moment including start-up, and then nothing was written or replaced
  (:class:`commission.infra.files.Outputs` removes its staging folder and lock).  Once
  the command's outputs are in place (:func:`commission.infra.files.committed_outputs`)
  the command is done as far as the files go: a signal arriving from then on (or
  during the final move, which holds it) is noted on stderr and the command ends
  with its own code, 0 or 1.  The exit code thus always tells the truth: 130/143
  means nothing in place, 0/1 the complete set.  A signal that arrives while compiled
  numba code runs is taken once that code has returned (:mod:`commission.cli.interrupts`).
"""

from __future__ import annotations

import os
import re
import signal
import sys


# Ctrl-C during start-up: commission/__init__.py installs a handler (console script only)
# before any import takes time; run() replaces it once the command line is parsed.

import importlib  # noqa: E402
import time  # noqa: E402
from typing import Any, Optional  # noqa: E402

import typer  # noqa: E402
import typer.core  # noqa: E402
import typer.main  # noqa: E402
# typer >= 0.29 carries its own adapted copy of click; these are its names.
from typer._click.core import Command as _Command, Context as _Context  # noqa: E402
from typer._click.exceptions import ClickException, UsageError  # noqa: E402

from commission import __version__  # noqa: E402
from commission.cli import commands  # noqa: E402
from commission.cli import interrupts  # noqa: E402
from commission.cli import verbosity  # noqa: E402

EXIT_INTERRUPTED = 130  # 128 + SIGINT
EXIT_TERMINATED = 143  # 128 + SIGTERM


class Terminated(BaseException):
    """Raised in the main thread on SIGTERM, so that ``finally`` blocks and :class:`Outputs` clean up."""


#: ``-h`` as an alias of ``--help``, for the group and every command.
HELP_SETTINGS = {"help_option_names": ["-h", "--help"]}


def _type_label(p: Any, ctx: _Context) -> str:
    if getattr(p, "is_flag", False) or getattr(p, "is_bool_flag", False):
        return ""
    shown = str(p.display_type(ctx) or "").strip()
    if shown.startswith("<") and shown.endswith(">"):
        shown = shown[1:-1]
    if shown.startswith("list[") and shown.endswith("]"):
        shown = shown[5:-1]
    if "|" in shown:
        return shown
    return {"str": "TEXT", "int": "INTEGER", "bool": ""}.get(shown, shown.upper())


def _readable_metavars(cmd: _Command) -> _Command:
    """Click-style metavars (``PATH``, ``FLOAT``, ``TEXT``, ``auto|coulomb|stribeck``, ``LOG``) instead
    of typer's ``<path>``, ``<list[str]>``, ``{log}``; flags show none."""
    ctx = _Context(cmd, **HELP_SETTINGS)
    for p in cmd.get_params(ctx):
        if getattr(p, "_readable", False):
            continue
        label = _type_label(p, ctx)
        p.display_type_rich = lambda ctx=None, _label=label: _label
        if isinstance(p, typer.core.TyperArgument):
            name = (p.name or "arg").upper()
            p.metavar = name
            p._usage_display_name = lambda _n=name, _req=p.required: _n if _req else f"[{_n}]"
        p._readable = True
    return cmd


class LazyGroup(typer.core.TyperGroup):
    """The command group, importing a command's module only when that command is needed.

    Commands are listed in pipeline order (:data:`commission.cli.commands.COMMANDS`);
    ``commission --help`` takes their one-line help from that table, so it imports
    none of them.
    """

    def list_commands(self, ctx: _Context) -> list[str]:
        extra = [n for n in super().list_commands(ctx) if n not in commands.COMMANDS]
        return [*commands.COMMANDS, *extra]

    def get_command(self, ctx: _Context, name: str) -> Optional[_Command]:
        if name in commands.COMMANDS and name not in self.commands:
            module, _short = commands.COMMANDS[name]
            importlib.import_module(module)  # registers the command on ``app``
            for info in app.registered_commands:
                if info.name == name:
                    self.add_command(typer.main.get_command_from_info(
                        info, pretty_exceptions_short=app.pretty_exceptions_short,
                        rich_markup_mode=app.rich_markup_mode), name)
                    break
        cmd = super().get_command(ctx, name)
        if cmd is not None and not isinstance(cmd, _Placeholder):
            # also for a command typer built itself (its module was imported before this group)
            if "help_option_names" not in (cmd.context_settings or {}):
                cmd.context_settings = {**HELP_SETTINGS, **(cmd.context_settings or {})}
            _readable_metavars(cmd)
        return cmd

    def format_help(self, ctx: _Context, formatter: Any) -> None:
        # typer's rich help asks every command for its help text, which would import them all:
        # register light placeholders carrying the one-line help instead.
        for n, (_module, short) in commands.COMMANDS.items():
            if n not in self.commands:
                self.commands[n] = _Placeholder(n, short)
        _readable_metavars(self)
        try:
            super().format_help(ctx, formatter)
        finally:
            for n in list(self.commands):
                if isinstance(self.commands[n], _Placeholder):
                    del self.commands[n]


class _Placeholder(typer.core.TyperCommand):
    """A command's name and one-line help, for the group's help page only."""

    def __init__(self, name: str, short: str) -> None:
        super().__init__(name, help=short, short_help=short)


app = typer.Typer(
    name="commission",
    help=("Commission a precision linear-motor axis: identify -> tune -> validate -> run (Xu & Yao 2001 ARC). "
          "Log format, JSON keys with units, exit codes and the runtime API: docs/interface.md."),
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=True,
    cls=LazyGroup,
    context_settings=HELP_SETTINGS,
)


@app.callback(invoke_without_command=True)
def _root(
    version: bool = typer.Option(False, "--version", help="Print the version and exit."),
    quiet: bool = typer.Option(False, "--quiet", "-q",
                               help="Print only errors and warnings: no tables, progress bars or 'wrote' lines."),
    verbose: bool = typer.Option(False, "--verbose", "-v",
                                 help="Also print the elapsed time, and the traceback of an internal error."),
) -> None:
    if version:
        typer.echo(__version__)
        raise typer.Exit(0)
    if quiet and verbose:
        raise UsageError("--quiet and --verbose exclude each other")
    verbosity.set_level(verbosity.QUIET if quiet else verbosity.VERBOSE if verbose else verbosity.NORMAL)


def _crash_log(exc: BaseException) -> str:
    """Write the traceback of an unexpected error to a log file; return its path."""
    import tempfile
    import traceback

    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    fd, path = tempfile.mkstemp(prefix=f"commission-crash-{stamp}-", suffix=".log")
    with os.fdopen(fd, "w") as fh:
        fh.write(f"commission {__version__}, python {sys.version.split()[0]}\n")
        fh.write(f"argv: {sys.argv!r}\n\n")
        fh.write("".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    return path


def _signal_cause(exc: BaseException) -> BaseException | None:
    """The signal's exception behind ``exc``, if the signal is what raised it (else None).

    A signal that arrives while Python runs a hook of its own (``__set_name__`` while a class is
    created at import, say) comes out wrapped, as a RuntimeError whose cause is the signal's
    KeyboardInterrupt or Terminated: that is the signal, not an internal error.
    """
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, (KeyboardInterrupt, Terminated)):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


def _internal_error(exc: BaseException) -> int:
    what = "out of memory" if isinstance(exc, MemoryError) else f"internal error ({type(exc).__name__}: {exc})"
    what = " ".join(what.split())[:300]
    try:
        where = f"please report it with the log {_crash_log(exc)}"
    except OSError as log_exc:
        where = f"please report it (the log could not be written: {log_exc.strerror or log_exc})"
    if verbosity.level() >= verbosity.VERBOSE:
        import traceback

        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    sys.stderr.write(f"error: {what}; {where}\n")
    return 2


def run(argv: list[str] | None = None) -> int:
    """Run the command line on ``argv`` (default: ``sys.argv[1:]``); return the exit code."""
    from commission.infra import files

    files.forget_commits()
    outer = files.unfinished()  # a caller's own (run() called in-process): not this command's to abort
    late: list[int] = []  # signals that came once the outputs were in place, or the command had ended
    ended = False

    def on_signal(signum: int, frame: object) -> None:
        # Before the outputs are in place: stop the command (Outputs then removes what it staged).
        # After: the files are complete and the command's own exit code is the truthful one.
        if ended or files.committed_outputs():
            late.append(signum)
            return
        if interrupts.in_compiled_code(frame):  # raising here would crash the kernel, not stop the command
            interrupts.redeliver(signum)
            return
        raise KeyboardInterrupt() if signum == signal.SIGINT else Terminated()

    old = signal.signal(signal.SIGINT, on_signal), signal.signal(signal.SIGTERM, on_signal)
    old_hook = sys.unraisablehook
    swallowed: list[BaseException] = []

    def unraisable(u: Any) -> None:
        # A signal's exception raised inside a finaliser (__del__, a weakref callback) cannot
        # propagate: note it quietly instead of printing "Exception ignored ... Traceback", and end
        # with its exit code once the command is done (its outputs are then complete).
        if isinstance(u.exc_value, (KeyboardInterrupt, Terminated)):
            swallowed.append(u.exc_value)
        else:
            old_hook(u)

    sys.unraisablehook = unraisable
    start = time.perf_counter()
    try:
        try:
            cmd = typer.main.get_command(app)
            rc: Any = cmd.main(args=argv, prog_name="commission", standalone_mode=False)
        finally:
            ended = True
            files.abort_unfinished(keep=outer)  # an interrupt between two statements may have skipped a cleanup
        code = rc if isinstance(rc, int) else 0
        if code == EXIT_INTERRUPTED:  # typer turns a KeyboardInterrupt into this code itself
            _say("interrupted: no output written or replaced")
    except typer.Exit as exc:
        code = exc.exit_code
    except ClickException as exc:  # usage errors: one line naming the flag
        msg = _did_you_mean(" ".join(exc.format_message().split()))
        sys.stderr.write(f"error: {msg} (see commission {_sub(argv)}--help)\n")
        code = 2
    except (typer.Abort, KeyboardInterrupt):
        _say("interrupted: no output written or replaced")
        code = EXIT_INTERRUPTED
    except Terminated:
        _say("terminated: no output written or replaced")
        code = EXIT_TERMINATED
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    except Exception as exc:  # noqa: BLE001 - the one place that catches what escapes
        sig = _signal_cause(exc)
        if sig is None:
            code = _internal_error(exc)
        elif isinstance(sig, Terminated):
            _say("terminated: no output written or replaced")
            code = EXIT_TERMINATED
        else:
            _say("interrupted: no output written or replaced")
            code = EXIT_INTERRUPTED
    finally:
        ended = True
        files.abort_unfinished(keep=outer)
        sys.unraisablehook = old_hook
        verbose = verbosity.level() >= verbosity.VERBOSE
        verbosity.restore_stdout()
    try:
        if (late or swallowed) and code in (0, 1):
            # The command finished (an interrupt raised inside a finaliser cannot propagate) or its
            # outputs were already in place: its code stands, and says so.
            term = signal.SIGTERM in late or any(isinstance(e, Terminated) for e in swallowed)
            what = "after the outputs were complete: kept them" if files.committed_outputs() else "as it finished"
            _say(f"{'terminated' if term else 'interrupted'} {what} (exit {code})")
        if verbose:
            sys.stderr.write(f"elapsed {time.perf_counter() - start:.2f} s\n")
        _decided[:] = [code]  # before the handlers go back: a signal from now on cannot change it
    finally:
        signal.signal(signal.SIGINT, old[0])
        signal.signal(signal.SIGTERM, old[1])
    return code


def _did_you_mean(msg: str) -> str:
    """Click's "No such command 'identfy'." with the closest command names (options get theirs from click)."""
    import difflib

    m = re.match(r"No such command '(.+)'\.?$", msg)
    if not m:
        return msg
    close = difflib.get_close_matches(m.group(1), list(commands.COMMANDS), n=2, cutoff=0.6)
    return msg if not close else f"{msg} Did you mean {' or '.join(repr(c) for c in close)}?"


def _say(line: str) -> None:
    # Straight to the file descriptor: a progress display may still hold sys.stderr.
    try:
        os.write(2, f"{line}\n".encode())
    except OSError:
        pass


def _sub(argv: list[str] | None) -> str:
    args = sys.argv[1:] if argv is None else argv
    sub = next((a for a in args if a in commands.COMMANDS), None)
    return f"{sub} " if sub else ""


#: The exit code :func:`run` decided, for :func:`_ending` (empty until then).
_decided: list[int] = []


def _ending(signum: int, frame: object) -> None:
    """SIGINT/SIGTERM outside :func:`run` in the console script: before it, nothing has been
    written (as during start-up, ``commission/__init__.py``); after it, the exit code is
    decided and a late signal ends the process with that code, not with 128 + the signal."""
    if not _decided:
        _say("interrupted")
        os._exit(128 + signum)
    _flush()
    os._exit(_decided[0])


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, RuntimeError):  # a closed pipe (commission ... | head); a re-entrant flush
            pass


def main() -> None:
    """Console-script entry.

    The process ends with :func:`os._exit` once the atexit functions have run and the
    streams are flushed: the rest of the interpreter's shutdown (garbage collection,
    module teardown, which numba and matplotlib make slow) runs after Python has put
    SIGINT and SIGTERM back to their default action, and a signal then would kill the
    process -- a shell reports 130 or 143 -- after a command whose outputs are complete
    and whose exit code is 0.  Nothing the tool writes depends on that teardown: every
    output is closed and moved into place by then.
    """
    import atexit

    _decided.clear()
    signal.signal(signal.SIGINT, _ending)
    signal.signal(signal.SIGTERM, _ending)
    code = run()
    _flush()
    try:
        atexit._run_exitfuncs()
    finally:
        _flush()
        os._exit(code)
