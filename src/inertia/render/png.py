"""PNG files without dependencies: 8-bit RGB/RGBA/grey, deterministic bytes (same image -> same file).

`write_png` uses filter type "up" on every row and zlib level 6; `read_png` reads 8-bit
non-interlaced PNGs of colour types grey, RGB and RGBA with any of the five row filters
(what this module and most encoders write). Written atomically.

Reference: W3C (2003). Portable Network Graphics (PNG) Specification, Second Edition.

Limitations: no palette, 16-bit or interlaced images on reading; no metadata chunks.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np
from numba import njit

from ..io.atomic import atomic_write

__all__ = ["encode_png", "write_png", "read_png"]

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_COLOR_TYPES = {1: 0, 3: 2, 4: 6}  # channels -> PNG colour type


def _chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload) & 0xFFFFFFFF)


def encode_png(image: np.ndarray, *, level: int = 6) -> bytes:
    """The PNG bytes of ``image`` (H, W), (H, W, 3) or (H, W, 4) uint8."""
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise ValueError(f"encode_png: image must be uint8, got {image.dtype}")
    if image.ndim == 2:
        image = image[:, :, None]
    if image.ndim != 3 or image.shape[2] not in _COLOR_TYPES:
        raise ValueError(f"encode_png: image must be (H, W), (H, W, 3) or (H, W, 4), got {image.shape}")
    height, width, channels = image.shape
    # Filter "up" (type 2): each row minus the row above, modulo 256; the first row unfiltered.
    rows = image.reshape(height, width * channels)
    filtered = np.empty((height, width * channels + 1), np.uint8)
    filtered[:, 0] = 2
    filtered[0, 0] = 0
    filtered[0, 1:] = rows[0]
    filtered[1:, 1:] = rows[1:] - rows[:-1]
    header = struct.pack(">IIBBBBB", width, height, 8, _COLOR_TYPES[channels], 0, 0, 0)
    return _SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(filtered.tobytes(), level)) + _chunk(b"IEND", b"")


def write_png(path: str | os.PathLike, image: np.ndarray, *, level: int = 6) -> Path:
    """Write ``image`` as a PNG file (atomically); returns the path."""
    data = encode_png(image, level=level)
    with atomic_write(path, "wb") as handle:
        handle.write(data)
    return Path(path)


@njit(cache=True)
def _unfilter(raw, bpp, out):
    """Undo the per-row PNG filters: raw (H, 1 + stride) -> out (H, stride), all uint8."""
    height, stride = out.shape
    for y in range(height):
        kind = raw[y, 0]
        for x in range(stride):
            value = np.int32(raw[y, x + 1])
            left = np.int32(out[y, x - bpp]) if x >= bpp else 0
            up = np.int32(out[y - 1, x]) if y > 0 else 0
            up_left = np.int32(out[y - 1, x - bpp]) if (x >= bpp and y > 0) else 0
            if kind == 1:
                value += left
            elif kind == 2:
                value += up
            elif kind == 3:
                value += (left + up) // 2
            elif kind == 4:
                p = left + up - up_left
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - up_left)
                if pa <= pb and pa <= pc:
                    value += left
                elif pb <= pc:
                    value += up
                else:
                    value += up_left
            elif kind != 0:
                return y  # bad filter type on this row
            out[y, x] = value & 0xFF
    return -1


def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read an 8-bit PNG as (H, W, C) uint8 (C = 1, 3 or 4)."""
    data = Path(path).read_bytes()
    if not data.startswith(_SIGNATURE):
        raise ValueError(f"{path}: not a PNG file")
    pos, idat, header = 8, [], None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        payload = data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", payload)
        elif kind == b"IDAT":
            idat.append(payload)
        elif kind == b"IEND":
            break
    if header is None:
        raise ValueError(f"{path}: PNG without IHDR")
    width, height, depth, color_type, _, _, interlace = header
    channels = {0: 1, 2: 3, 6: 4}.get(color_type)
    if depth != 8 or channels is None or interlace:
        raise ValueError(f"{path}: only 8-bit non-interlaced grey/RGB/RGBA PNGs are read (got depth {depth}, type {color_type})")
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8).reshape(height, width * channels + 1)
    out = np.empty((height, width * channels), np.uint8)
    bad = _unfilter(raw, channels, out)
    if bad >= 0:
        raise ValueError(f"{path}: bad PNG filter type {raw[bad, 0]} on row {bad}")
    return out.reshape(height, width, channels)
