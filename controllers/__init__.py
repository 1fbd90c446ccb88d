"""Pure numerics of the closed loop: plant, controllers, trajectories, indexes.

Never imports typer, h5py or matplotlib.
"""

from __future__ import annotations

import os as _os


def drop_stale_kernel_cache(here: str, dependants: tuple[str, ...] = ("synth",), dependants_root: str | None = None) -> None:
    """Remove numba's on-disk kernels when any source of this package changed.

    numba keys a cached kernel on the time stamp of the file that defines it, not on
    the jitted functions it inlines from other modules: after an edit of ``plant.py``,
    ``simulate.py``'s cached closed loop would still run the old plant.  A sha256 over
    every source of this package and of its subpackages (``arc/``, ...) is kept beside the
    cache; when it differs, the cached kernels of this package, of its subpackages and of
    the modules that inline it (``commission.synth``, a module ``<name>.py`` or a package
    ``<name>/`` beside this one, or in ``dependants_root`` when given: ``dependants`` names them)
    are dropped and recompiled on first use.  In an installed tree ``commission.synth`` sits beside
    this package; in an editable install this package is the repository's ``controllers/`` and
    ``commission.synth`` is under ``commission/``, hence ``dependants_root``.  Costs one read of the sources per import.  A read-only install (where
    numba cannot cache either) is left alone.
    """
    import hashlib
    import os

    try:
        digest = hashlib.sha256()
        folders = [here]  # this package and its subpackages, at any depth
        for folder in folders:
            for name in sorted(os.listdir(folder)):
                path = os.path.join(folder, name)
                if name.endswith(".py"):
                    with open(path, "rb") as fh:
                        digest.update(os.path.relpath(path, here).encode() + b"\0" + fh.read() + b"\0")
                elif os.path.isfile(os.path.join(path, "__init__.py")):
                    folders.append(path)
        stamp = os.path.join(here, "__pycache__", "kernel-sources.sha256")
        try:
            with open(stamp, encoding="ascii") as fh:
                if fh.read().strip() == digest.hexdigest():
                    return
        except (OSError, UnicodeDecodeError):
            pass
        parent = os.path.dirname(here)
        caches = [os.path.join(here, "__pycache__"), os.path.join(parent, "__pycache__"),
                  *(os.path.join(dependants_root or parent, d, "__pycache__") for d in dependants),
                  *(os.path.join(f, "__pycache__") for f in folders[1:])]
        prefixes = tuple(f"{d}." for d in dependants)
        for cache in caches:
            if not os.path.isdir(cache):
                continue
            for f in os.listdir(cache):
                if f.endswith((".nbi", ".nbc")) and (cache != caches[1] or f.startswith(prefixes)):
                    try:
                        os.remove(os.path.join(cache, f))
                    except FileNotFoundError:
                        pass  # another process dropped it first
        os.makedirs(caches[0], exist_ok=True)
        tmp = f"{stamp}.{os.getpid()}"
        with open(tmp, "w", encoding="ascii") as fh:
            fh.write(digest.hexdigest() + "\n")
        os.replace(tmp, stamp)
    except OSError:
        return


def _commission_dir() -> str | None:
    """Where the ``commission`` package is (imported before this subpackage), or None."""
    import sys

    top = getattr(sys.modules.get("commission"), "__file__", None)
    return _os.path.dirname(_os.path.abspath(top)) if top else None


drop_stale_kernel_cache(_os.path.dirname(_os.path.abspath(__file__)), dependants_root=_commission_dir())
