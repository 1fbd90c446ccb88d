"""Writers of excitation logs for the loader tests, independent of the loader.

Each writes its format in the layout that format's own tools use (h5py, numpy's
CSV, scipy's MAT v5, MATLAB's v7.3 = HDF5 behind a 512-byte header).
"""

from __future__ import annotations

import h5py
import numpy as np
import scipy.io

N = 600
FS = 1000.0


def reference_arrays(n: int = N) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    t = np.arange(n) / FS
    q_ref = 0.05 * np.sin(2 * np.pi * 0.5 * t)
    q = np.round((q_ref + 1e-5 * rng.standard_normal(n)) / 1e-6) * 1e-6  # 1 um encoder
    u = 2.0 * np.sin(2 * np.pi * 0.5 * t + 0.3) + 0.01 * rng.standard_normal(n)
    return {"t": t, "q": q, "u": u, "q_ref": q_ref}


def write_h5(path, arrays, attrs=None) -> None:
    with h5py.File(path, "w") as f:
        for k, v in arrays.items():
            f.create_dataset(k, data=v)
        for k, v in (attrs or {}).items():
            f.attrs[k] = v


def write_csv(path, arrays) -> None:
    names = list(arrays)
    table = np.column_stack([arrays[k] for k in names])
    # %.17g round-trips every float64 exactly.
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.17g")


def write_mat5(path, arrays) -> None:
    scipy.io.savemat(path, {k: np.asarray(v)[:, None] for k, v in arrays.items()})  # N×1 like EMPS


def write_mat73(path, arrays, attrs=None, matlab_class="double") -> None:
    """HDF5 with MATLAB's v7.3 layout: 512-byte userblock header, arrays stored transposed."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for k, v in arrays.items():
            ds = f.create_dataset(k, data=np.asarray(v)[None, :])  # MATLAB N×1 -> HDF5 (1, N)
            ds.attrs["MATLAB_class"] = np.bytes_(matlab_class)
        for k, v in (attrs or {}).items():
            f.attrs[k] = v
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    header = text.ljust(116) + b"\x00" * 8 + b"\x00\x02" + b"IM"
    with open(path, "r+b") as fh:
        fh.write(header)


WRITERS = {
    "h5": write_h5,
    "csv": write_csv,
    "mat": write_mat5,
    "v73.mat": write_mat73,
}
