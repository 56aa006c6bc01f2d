"""Export grid fluids as VTK image data (``.vti``, VTK XML format 1.0) for ParaView, written with
NumPy only (no VTK dependency).

Each file holds one frame: the grid's cells (``WholeExtent`` 0..nx, 0..ny, 0..nz points, origin
and spacing in metres) with cell data arrays: every scalar of the fluid, ``velocity`` (cell-
centred average of the face velocities, 3 components, m/s) and ``pressure`` when present.
Arrays are stored inline as base64 binary (``header_type="UInt32"``: a 4-byte byte count, then
the little-endian values), x fastest as VTK expects.

Reference: Kitware, "VTK File Formats" (the VTK User's Guide, XML formats: ImageData).

Limitations: one file per frame (no ``.pvd`` collection written); a 2-D grid is written as one
cell layer in z; cell data only (no point data); files are not compressed.
"""

from __future__ import annotations

import base64
import os

import numpy as np


def _encode(a):
    """VTK inline binary: base64 of UInt32 byte count + data (little-endian, x fastest)."""
    order = (2, 1, 0) if a.ndim == 3 else (2, 1, 0, 3)
    data = np.ascontiguousarray(a.transpose(order))
    raw = data.astype(data.dtype.newbyteorder("<"), copy=False).tobytes()
    return base64.b64encode(np.uint32(len(raw)).tobytes() + raw).decode("ascii")


def cell_arrays(fluid):
    """dict name -> (nx, ny, nz) or (nx, ny, nz, 3) float32 cell arrays of a `GridFluid`."""
    out = {}
    for name, a in zip(fluid.scalar_names, fluid._scal):
        out[name] = a.astype(np.float32)
    u, v, w = fluid._vel
    vel = np.zeros(tuple(fluid.grid.n) + (3,), dtype=np.float32)
    vel[..., 0] = 0.5 * (u[1:] + u[:-1])
    vel[..., 1] = 0.5 * (v[:, 1:] + v[:, :-1])
    if fluid.dim == 3:
        vel[..., 2] = 0.5 * (w[:, :, 1:] + w[:, :, :-1])
    out["velocity"] = vel
    out["phi"] = fluid.phi.astype(np.float32)
    return out


def write_vti(path, fluid, arrays=None):
    """Write `fluid` (a GridFluid) or explicit `arrays` (dict of (nx, ny, nz[, 3]) arrays) on the
    fluid's grid to `path` (.vti). Returns the path."""
    path = os.fspath(path)
    if not path.endswith(".vti"):
        raise ValueError(f"path must end with .vti; got {path!r}")
    g = fluid.grid
    nx, ny, nz = (int(s) for s in g.n)
    arrays = cell_arrays(fluid) if arrays is None else arrays
    h = g.cell_size
    ox, oy, oz = (float(x) for x in g.origin3)
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" header_type="UInt32">',
             f'  <ImageData WholeExtent="0 {nx} 0 {ny} 0 {nz}" Origin="{ox!r} {oy!r} {oz!r}" '
             f'Spacing="{h!r} {h!r} {h!r}">',
             f'    <Piece Extent="0 {nx} 0 {ny} 0 {nz}">',
             '      <CellData>']
    for name, a in arrays.items():
        a = np.asarray(a)
        if a.shape[:3] != (nx, ny, nz) or a.ndim not in (3, 4):
            raise ValueError(f"arrays[{name!r}] must have shape {(nx, ny, nz)} or {(nx, ny, nz, 3)}; "
                             f"got {a.shape}")
        comps = 1 if a.ndim == 3 else a.shape[3]
        typ = {np.dtype(np.float32): "Float32", np.dtype(np.float64): "Float64"}.get(a.dtype)
        if typ is None:
            a = a.astype(np.float32)
            typ = "Float32"
        lines.append(f'        <DataArray type="{typ}" Name="{name}" NumberOfComponents="{comps}" '
                     f'format="binary">{_encode(a)}</DataArray>')
    lines += ['      </CellData>', '    </Piece>', '  </ImageData>', '</VTKFile>', '']
    with open(path, "w", encoding="ascii") as fh:
        fh.write("\n".join(lines))
    return path


def read_vti(path):
    """Parse a .vti written by `write_vti` back: (origin (3,), spacing (3,), extent (6,),
    dict name -> (nx, ny, nz[, comps]) array). For tests and round trips."""
    import xml.etree.ElementTree as ET
    root = ET.parse(path).getroot()
    img = root.find("ImageData")
    ext = np.array(img.get("WholeExtent").split(), dtype=np.int64)
    origin = np.array(img.get("Origin").split(), dtype=np.float64)
    spacing = np.array(img.get("Spacing").split(), dtype=np.float64)
    nx, ny, nz = ext[1] - ext[0], ext[3] - ext[2], ext[5] - ext[4]
    out = {}
    for da in img.iter("DataArray"):
        raw = base64.b64decode(da.text.strip())
        nbytes = int(np.frombuffer(raw[:4], dtype="<u4")[0])
        dtype = {"Float32": "<f4", "Float64": "<f8"}[da.get("type")]
        vals = np.frombuffer(raw[4:4 + nbytes], dtype=dtype)
        comps = int(da.get("NumberOfComponents", "1"))
        a = vals.reshape(nz, ny, nx, comps) if comps > 1 else vals.reshape(nz, ny, nx)
        out[da.get("Name")] = a.transpose(2, 1, 0, 3) if comps > 1 else a.transpose(2, 1, 0)
    return origin, spacing, ext, out
