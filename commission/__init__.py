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
    traceback; nothing has been written yet.  A program importing this package is not affected."""
    import os
    import signal
    import sys

    if not os.path.basename(sys.argv[0] if sys.argv else "").startswith("commission"):
        return

    def leave(signum: int, frame: object) -> None:
        os.write(2, b"interrupted\n")
        os._exit(128 + signum)

    signal.signal(signal.SIGINT, leave)
    signal.signal(signal.SIGTERM, leave)


_install_startup_interrupt()
