"""Argument checks shared by the public constructors.

Every check raises `ValueError` naming the argument and what is allowed.
"""

from __future__ import annotations

import numpy as np


def as_points(value, name: str, *, dim: int | None = None, count: int | None = None,
              allowed_dims=(2, 3)) -> np.ndarray:
    """Return `value` as a C-contiguous float64 array of shape (count, dim)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2:
        raise ValueError(
            f"{name} must be a 2-D array of shape (N, D) with D in {tuple(allowed_dims)}; "
            f"got an array of shape {arr.shape}")
    if dim is None and arr.shape[1] not in allowed_dims:
        raise ValueError(f"{name} must have {' or '.join(map(str, allowed_dims))} columns "
                         f"(2-D or 3-D points); got shape {arr.shape}")
    if dim is not None and arr.shape[1] != dim:
        raise ValueError(f"{name} must have shape (N, {dim}); got {arr.shape}")
    if count is not None and arr.shape[0] != count:
        raise ValueError(f"{name} must have {count} rows (one per particle); got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
        raise ValueError(f"{name} must be finite; rows {bad[:10].tolist()} contain NaN or inf")
    return np.ascontiguousarray(arr)


def as_vector(value, name: str, dim: int | None = None) -> np.ndarray:
    """Return `value` as a finite float64 vector of length `dim` (2 or 3 if not given)."""
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if dim is not None and arr.shape[0] != dim:
        raise ValueError(f"{name} must have {dim} components; got {arr.shape[0]}")
    if dim is None and arr.shape[0] not in (2, 3):
        raise ValueError(f"{name} must have 2 or 3 components; got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; got {arr.tolist()}")
    return arr


def per_item(value, name: str, count: int, *, positive=False, nonnegative=False,
             allow_inf=False) -> np.ndarray:
    """Broadcast a scalar or (count,) array to a float64 (count,) array and check its sign."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(count, float(arr))
    elif arr.shape != (count,):
        raise ValueError(f"{name} must be a scalar or an array of shape ({count},); got {arr.shape}")
    else:
        arr = arr.copy()
    finite = np.isfinite(arr) | (allow_inf & np.isposinf(arr))
    if not np.all(finite):
        raise ValueError(f"{name} must be finite{' or +inf' if allow_inf else ''}; "
                         f"bad entries at {np.flatnonzero(~finite)[:10].tolist()}")
    if positive and np.any(arr <= 0):
        raise ValueError(f"{name} must be > 0{' (use inf to pin)' if allow_inf else ''}; "
                         f"got {arr[arr <= 0][:5].tolist()} at {np.flatnonzero(arr <= 0)[:10].tolist()}")
    if nonnegative and np.any(arr < 0):
        raise ValueError(f"{name} must be >= 0; got negative entries at "
                         f"{np.flatnonzero(arr < 0)[:10].tolist()}")
    return arr


def positive_scalar(value, name: str, *, allow_zero=False) -> float:
    """Return `value` as a finite float > 0 (or >= 0 when `allow_zero`)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number; got {value!r}") from None
    if not np.isfinite(x) or x < 0 or (x == 0 and not allow_zero):
        raise ValueError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0; got {value!r}")
    return x


def index_array(value, name: str, count: int, *, columns: int | None = None) -> np.ndarray:
    """Return an int64 index array whose entries lie in [0, count)."""
    arr = np.asarray(value)
    if arr.size == 0:
        shape = (0, columns) if columns else (0,)
        return np.zeros(shape, dtype=np.int64)
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name} must hold integer particle indices; got dtype {arr.dtype}")
    if columns is not None and (arr.ndim != 2 or arr.shape[1] != columns):
        raise ValueError(f"{name} must have shape (M, {columns}); got {arr.shape}")
    if columns is None and arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array of indices; got shape {arr.shape}")
    if arr.min() < 0 or arr.max() >= count:
        bad = arr[(arr < 0) | (arr >= count)]
        raise ValueError(f"{name} indices must lie in [0, {count - 1}] (the particle count is {count}); "
                         f"got out-of-range values {np.unique(bad)[:10].tolist()}")
    return np.ascontiguousarray(arr, dtype=np.int64)


def npy_header(handle) -> tuple[tuple[int, ...], np.dtype, int]:
    """(shape, dtype, bytes of array data the header promises) of the ``.npy`` stream open in binary
    ``handle``, read from its header alone (nothing the size of the array is allocated), leaving the
    handle at the start of the data. Raises what numpy raises for a damaged header (ValueError, OSError,
    EOFError)."""
    import math

    version = np.lib.format.read_magic(handle)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(handle)
    else:
        shape, _, dtype = np.lib.format.read_array_header_2_0(handle)
    return shape, dtype, math.prod(shape) * dtype.itemsize
