"""The numba kernel cache is dropped when any source of the controllers package changes.

numba keys a cached kernel on its own file's time stamp only; a kernel that inlines a
function of another module would otherwise keep stale machine code after that module
is edited (commission.controllers.drop_stale_kernel_cache)."""

from __future__ import annotations

import os

from pathlib import Path

from commission.controllers import drop_stale_kernel_cache


def _kernels(folder: Path) -> list[str]:
    return sorted(f.name for f in folder.glob("*.nb*"))


def _layout(tmp_path: Path) -> tuple[Path, Path, Path]:
    pkg = tmp_path / "controllers"
    (pkg / "__pycache__").mkdir(parents=True)
    (tmp_path / "__pycache__").mkdir()
    (pkg / "plant.py").write_text("def f(x):\n    return x\n")
    (pkg / "simulate.py").write_text("def g(x):\n    return x\n")
    return pkg, pkg / "__pycache__", tmp_path / "__pycache__"


def _cache_some(own: Path, parent: Path) -> None:
    for f in (own / "simulate.g-1.py311.nbi", own / "simulate.g-1.py311.1.nbc", parent / "synth.h-3.py311.nbi",
              parent / "other.k-2.py311.nbi"):
        f.write_bytes(b"x")


def test_an_unchanged_package_keeps_its_kernels_and_an_edit_drops_them_and_their_dependants(tmp_path):
    pkg, own, parent = _layout(tmp_path)
    drop_stale_kernel_cache(str(pkg))  # first sight: no stamp yet, nothing to keep
    _cache_some(own, parent)
    drop_stale_kernel_cache(str(pkg))
    assert _kernels(own) == ["simulate.g-1.py311.1.nbc", "simulate.g-1.py311.nbi"]
    assert _kernels(parent) == ["other.k-2.py311.nbi", "synth.h-3.py311.nbi"]

    (pkg / "plant.py").write_text("def f(x):\n    return 2 * x\n")  # an inlined callee changes
    drop_stale_kernel_cache(str(pkg))
    assert _kernels(own) == []
    assert _kernels(parent) == ["other.k-2.py311.nbi"]  # a module that does not inline the package stays

    _cache_some(own, parent)
    drop_stale_kernel_cache(str(pkg))  # recompiled against the new source: kept from now on
    assert _kernels(own) == ["simulate.g-1.py311.1.nbc", "simulate.g-1.py311.nbi"]


def test_a_stamp_that_cannot_be_written_does_not_stop_the_import(tmp_path):
    pkg, own, parent = _layout(tmp_path)
    (own / "kernel-sources.sha256").mkdir()  # cannot be written as a file: the guard gives up quietly
    _cache_some(own, parent)
    drop_stale_kernel_cache(str(pkg))
    assert (own / "kernel-sources.sha256").is_dir()


def test_a_dependant_package_beside_it_loses_its_kernels_too(tmp_path):
    """``commission.synth`` is a package: its kernels (which inline the plant) sit in ``synth/__pycache__``."""
    pkg, own, parent = _layout(tmp_path)
    dep = tmp_path / "synth" / "__pycache__"
    dep.mkdir(parents=True)
    drop_stale_kernel_cache(str(pkg))
    (dep / "simulation._closed_loop-19.py311.nbi").write_bytes(b"x")
    drop_stale_kernel_cache(str(pkg))
    assert _kernels(dep) == ["simulation._closed_loop-19.py311.nbi"]
    (pkg / "plant.py").write_text("def f(x):\n    return 3 * x\n")
    drop_stale_kernel_cache(str(pkg))
    assert _kernels(dep) == []


def test_a_dependant_elsewhere_is_found_under_its_root(tmp_path):
    """An editable install: ``controllers/`` is the repository's, ``commission/synth`` sits under ``commission/``."""
    pkg, own, parent = _layout(tmp_path)
    root = tmp_path / "commission"
    dep = root / "synth" / "__pycache__"
    dep.mkdir(parents=True)
    drop_stale_kernel_cache(str(pkg), dependants_root=str(root))
    (dep / "simulation._closed_loop-19.py311.nbi").write_bytes(b"x")
    (pkg / "plant.py").write_text("def f(x):\n    return 5 * x\n")
    drop_stale_kernel_cache(str(pkg), dependants_root=str(root))
    assert _kernels(dep) == []


def test_the_installed_guard_points_at_the_commission_package():
    import commission
    import commission.controllers as C

    assert C._commission_dir() == os.path.dirname(os.path.abspath(commission.__file__))


def test_an_edit_in_a_subpackage_drops_its_kernels_and_the_package_s(tmp_path):
    """``controllers/arc/`` is a subpackage: its step is inlined by ``simulate.py``'s kernels."""
    pkg, own, parent = _layout(tmp_path)
    sub = pkg / "arc"
    (sub / "__pycache__").mkdir(parents=True)
    (sub / "__init__.py").write_text("")
    (sub / "step.py").write_text("def s(x):\n    return x\n")
    (pkg / "notes").mkdir()  # a folder that is not a package is neither hashed nor cleaned
    (pkg / "notes" / "scratch.py").write_text("x = 1\n")
    drop_stale_kernel_cache(str(pkg))
    _cache_some(own, parent)
    (sub / "__pycache__" / "step.arc_step-9.py311.nbi").write_bytes(b"x")
    drop_stale_kernel_cache(str(pkg))
    assert _kernels(sub / "__pycache__") == ["step.arc_step-9.py311.nbi"]
    (pkg / "notes" / "scratch.py").write_text("x = 2\n")
    drop_stale_kernel_cache(str(pkg))
    assert _kernels(sub / "__pycache__") == ["step.arc_step-9.py311.nbi"]

    (sub / "step.py").write_text("def s(x):\n    return 2 * x\n")
    drop_stale_kernel_cache(str(pkg))
    assert _kernels(sub / "__pycache__") == []
    assert _kernels(own) == []
    assert _kernels(parent) == ["other.k-2.py311.nbi"]
