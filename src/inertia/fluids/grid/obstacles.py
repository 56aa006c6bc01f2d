"""Solid obstacles on the MAC grid: open face fractions from signed distances.

The open fraction A_f of a face is the part of its area outside every obstacle, estimated
from the signed distance at the face's corners (grid vertices) with the solid boundary taken
as the zero level set of the linear interpolant: exact for a segment (2-D), and for a square
face (3-D) split into four triangles around its centre (centre value = mean of the corners).
These fractions are the weights of the variational pressure projection of Batty, Bertails and
Bridson (2007), "A fast variational framework for accurate solid-fluid coupling" (SIGGRAPH),
which makes curved walls act smoothly instead of as staircases.

Limitations: features thinner than a cell are lost between vertices; fractions below
``MIN_FRACTION`` are set to 0 (they would only worsen the pressure system's conditioning).
"""

from __future__ import annotations

import numpy as np

MIN_FRACTION = 1e-3


def segment_fraction(a, b):
    """Fraction of the segment where the linear interpolant of end values a, b is > 0."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    out = np.where((a > 0) & (b > 0), 1.0, 0.0)
    mixed = (a > 0) != (b > 0)
    pos = np.maximum(a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(mixed, pos / (np.abs(a) + np.abs(b)), out)
    return out


def _triangle_fraction(a, b, c):
    """Area fraction of a triangle where the linear interpolant of vertex values is > 0."""
    npos = (a > 0).astype(int) + (b > 0) + (c > 0)
    out = np.where(npos == 3, 1.0, 0.0)
    # sort the values so the lone vertex is identifiable: lone positive (npos 1) or negative (2)
    v = np.stack([a, b, c])
    with np.errstate(invalid="ignore", divide="ignore"):
        # one positive vertex p, two negative n1, n2: fraction p^2 / ((p - n1)(p - n2))
        p1 = np.max(v, axis=0)
        others = np.sort(v, axis=0)[:2]
        f1 = p1 * p1 / ((p1 - others[0]) * (p1 - others[1]))
        # one negative vertex n, two positive: 1 - n^2 / ((n - p1)(n - p2))
        n1 = np.min(v, axis=0)
        others2 = np.sort(v, axis=0)[1:]
        f2 = 1.0 - n1 * n1 / ((n1 - others2[0]) * (n1 - others2[1]))
    out = np.where(npos == 1, f1, out)
    out = np.where(npos == 2, f2, out)
    return out


def square_fraction(c00, c10, c11, c01):
    """Area fraction of a square (corners in order around it) outside the solid."""
    centre = 0.25 * (c00 + c10 + c11 + c01)
    corners = [c00, c10, c11, c01]
    total = 0.0
    for q in range(4):
        total = total + _triangle_fraction(centre, corners[q], corners[(q + 1) % 4])
    return 0.25 * total


def face_fractions(vertex_sdf, dim):
    """Open fractions of the u, v, w faces from the signed distance at the grid vertices
    ((nx+1, ny+1, nz+1), nz+1 = 2 in 2-D with both layers equal). Returns three 3-D arrays."""
    s = vertex_sdf
    if dim == 2:
        s2 = s[:, :, 0]
        fu = segment_fraction(s2[:, :-1], s2[:, 1:])[:, :, None]
        fv = segment_fraction(s2[:-1, :], s2[1:, :])[:, :, None]
        fw = np.ones((s.shape[0] - 1, s.shape[1] - 1, 2))
    else:
        fu = square_fraction(s[:, :-1, :-1], s[:, 1:, :-1], s[:, 1:, 1:], s[:, :-1, 1:])
        fv = square_fraction(s[:-1, :, :-1], s[1:, :, :-1], s[1:, :, 1:], s[:-1, :, 1:])
        fw = square_fraction(s[:-1, :-1, :], s[1:, :-1, :], s[1:, 1:, :], s[:-1, 1:, :])
    out = []
    for f in (fu, fv, fw):
        f = np.clip(np.nan_to_num(f, nan=0.0), 0.0, 1.0)
        f[f < MIN_FRACTION] = 0.0
        out.append(np.ascontiguousarray(f))
    return out
