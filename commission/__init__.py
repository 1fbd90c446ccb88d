"""commission: commission precision linear-motor axes.

Pipeline layer (data model, I/O, orchestration).  The pure numerics live in
:mod:`commission.identify` and :mod:`commission.controllers`; the command line
in :mod:`commission.cli`.  Dependencies point one way: cli -> commission ->
identify, controllers.
"""

__version__ = "0.1.0"


def _install_startup_interrupt() -> None:
    """In the ``commission`` console script only: Ctrl-C or SIGTERM during start-up (the imports,
    before :func:`commission.cli.main.run` takes over) ends the process with one line and no
    traceback; nothing has been written yet.  A program importing this package is not affected.

    It uses the built-in ``_signal`` module (no Python-level import, unlike :mod:`signal`, whose
    enum set-up is itself a window in which an interrupt would print a traceback), and an
    interrupt that lands before the handlers are in place is caught the same way."""
    import os
    import sys

    if not os.path.basename(sys.argv[0] if sys.argv else "").startswith("commission"):
        return

    def leave(signum: int, frame: object) -> None:
        os.write(2, b"interrupted\n")
        os._exit(128 + signum)

    try:
        import _signal

        _signal.signal(_signal.SIGINT, leave)
        _signal.signal(_signal.SIGTERM, leave)
    except KeyboardInterrupt:
        leave(2, None)


_install_startup_interrupt()
