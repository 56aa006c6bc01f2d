"""Seeded gradient noise (simplex and improved Perlin) in 2-D, 3-D and 4-D, with fractal octaves.

``Noise`` is a scalar field N(x, t) with analytic gradient and Hessian, evaluated in parallel
over many points by the Numba kernels in ``kernels.py``:

    N(x, t) = amplitude * sum_o gain^o n(f_o x + s_o, f_o tf t + s_o,t) / sum_o gain^o,
    f_o = frequency * lacunarity^o,   o = 0 .. octaves - 1,

where n is one octave of unit-range lattice noise, tf is ``time_frequency`` (time becomes one
more lattice axis when it is nonzero: 2-D space + time uses 3-D noise, 3-D space + time 4-D
noise) and s_o is a seeded offset per octave that decorrelates the octaves.

Range: every octave n is divided by the largest value the lattice construction can reach with
any assignment of gradients to corners (computed numerically for each kind and dimension,
``_BOUND``), so |n| <= 1 and |N| <= amplitude everywhere (the bound is reached: one octave of
2-D or 3-D simplex noise gets within 0.1 % of it). The mean over many lattice cells is 0
(every gradient g has its opposite -g in the table). Standard deviation of one octave, as a
fraction of the bound, for lattices of 2 / 3 / 4 axes: simplex 0.54 / 0.39 / 0.25, Perlin
0.31 / 0.26 / 0.19; a 3-octave sum (gain 0.5) has about 0.65 times that.

References
----------
- Perlin, K. (1985), "An image synthesizer", SIGGRAPH '85: gradient (lattice) noise.
- Perlin, K. (2002), "Improving noise", SIGGRAPH '02 (ACM TOG 21(3)): quintic fade and
  the 12 (+4 repeated) edge gradients used by ``kind="perlin"`` in 3-D.
- Perlin, K. (2001), "Noise hardware", in *Real-Time Shading*, SIGGRAPH course notes, and
  Gustavson, S. (2005, rev. 2012), "Simplex noise demystified": the simplex lattice used by
  ``kind="simplex"`` (the default: D + 1 corners per point instead of 2^D).

Limitations
-----------
- Periodic with period 256 / f_o along every axis (a 256-entry permutation hashes the lattice).
- Simplex uses a radial kernel radius^2 of 0.5 (not Gustavson's 0.6) so the noise is C^2 with
  continuous derivatives in every dimension; Perlin noise is C^2 (quintic fade).
- Points are float64; far from the origin (|f x| > 1e9) the lattice position loses precision.
- Seeds are reproducible across platforms and NumPy versions (a SplitMix64 stream, not
  NumPy's generators) but the noise is not bit-compatible with other Perlin/simplex libraries.
"""

from __future__ import annotations

import itertools
import numbers
from dataclasses import dataclass

import numpy as np

from .._validate import as_points, positive_scalar
from . import kernels as K

__all__ = ["Noise"]

KINDS = ("simplex", "perlin")

# Largest unscaled single-octave value over all points and all gradient assignments
# (max over x of sum_corners weight_c(x) * max_g |g . d_c(x)|), found by dense sampling and local
# maximisation, rounded up. Dividing by it makes |n| <= 1.
_BOUND = {
    ("simplex", 2): 0.0100588,
    ("simplex", 3): 0.0091975,
    ("simplex", 4): 0.0091968,
    ("perlin", 2): 0.69536,
    ("perlin", 3): 0.73282,
    ("perlin", 4): 0.88715,
}


def _gradient_table(D: int) -> np.ndarray:
    """Unit gradient vectors; their count divides 256 so that ``hash % count`` is unbiased.

    2-D: 16 directions; 3-D: Perlin's 12 cube-edge directions plus 4 repeated (2002);
    4-D: the 32 edge directions of the 4-cube. Each set holds -g for every g (zero mean).
    """
    if D == 2:
        a = 2.0 * np.pi * (np.arange(16) + 0.5) / 16.0
        g = np.stack([np.cos(a), np.sin(a)], axis=1)
    elif D == 3:
        g = np.array([(1, 1, 0), (-1, 1, 0), (1, -1, 0), (-1, -1, 0),
                      (1, 0, 1), (-1, 0, 1), (1, 0, -1), (-1, 0, -1),
                      (0, 1, 1), (0, -1, 1), (0, 1, -1), (0, -1, -1),
                      (1, 1, 0), (-1, 1, 0), (0, -1, 1), (0, -1, -1)], dtype=np.float64) / np.sqrt(2.0)
    else:
        rows = []
        for zero in range(4):
            for signs in itertools.product((-1.0, 1.0), repeat=3):
                v = list(signs)
                v.insert(zero, 0.0)
                rows.append(v)
        g = np.array(rows) / np.sqrt(3.0)
    return np.ascontiguousarray(g, dtype=np.float64)


_GRADIENTS = {D: _gradient_table(D) for D in (2, 3, 4)}

_MASK64 = (1 << 64) - 1


def _splitmix64(seed: int):
    """SplitMix64 (Steele, Lea & Flood 2014): a platform-independent stream of 64-bit integers."""
    state = seed & _MASK64
    while True:
        state = (state + 0x9E3779B97F4A7C15) & _MASK64
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
        yield z ^ (z >> 31)


def lattice_tables(seed: int, components: int, octaves: int):
    """Permutation (512,) int64 (256 entries, repeated) and offsets (components, octaves, 4).

    Offsets are uniform in [0, 256) lattice cells: each potential component and octave reads
    a different, uncorrelated region of the same periodic lattice.
    """
    stream = _splitmix64(seed)
    perm = list(range(256))
    for i in range(255, 0, -1):  # Fisher-Yates shuffle
        j = next(stream) % (i + 1)
        perm[i], perm[j] = perm[j], perm[i]
    offsets = np.empty((components, octaves, 4))
    for c in range(components):
        for o in range(octaves):
            for k in range(4):
                offsets[c, o, k] = (next(stream) >> 11) * (256.0 / (1 << 53))
    return np.array(perm + perm, dtype=np.int64), offsets


def component_gradients(seed: int, components: int, D: int) -> np.ndarray:
    """Gradient tables of `components` noises that share one lattice: (components, 256, D).

    Entry [c, h] is the gradient noise c takes at a lattice corner whose hash is h, so several
    noises are read with one lattice walk (one hash per corner) and one dot product each.
    Table 0 is the base table repeated (``grads[h % count]``: the same noise as ``Noise``).
    Tables 1 and 2 (3-D curl-noise's other potentials) are seeded so that, over the 256
    hashes, every table has zero mean and any two tables have exactly zero covariance
    (sum_h T_a[h] T_b[h]^T = 0): the hashes holding one gradient of table 0 are split into
    groups of four that take (+a, +b), (-a, +b), (+a, -b), (-a, -b) in tables 1 and 2, with
    a and b drawn evenly from the base table. The three potentials are therefore uncorrelated,
    as three independent noises are, although they sample the same lattice points.
    """
    base = _GRADIENTS[D]
    count = base.shape[0]
    tables = np.empty((components, 256, D))
    tables[0] = base[np.arange(256) % count]
    if components == 1:
        return tables
    if components != 3:
        raise ValueError(f"components must be 1 or 3; got {components!r}")
    stream = _splitmix64(seed ^ 0x2545F4914F6CDD1D)

    def shuffled(values):
        values = list(values)
        for i in range(len(values) - 1, 0, -1):  # Fisher-Yates
            j = next(stream) % (i + 1)
            values[i], values[j] = values[j], values[i]
        return values

    # Hashes grouped by their table-0 gradient (h % count), each group in seeded order, then
    # cut into fours; 256 / count (16 in 3-D, 8 in 4-D) hashes per gradient.
    order = [h for g in range(count) for h in shuffled(range(g, 256, count))]
    a_rows = shuffled(np.arange(64) % count)
    b_rows = shuffled(np.arange(64) % count)
    signs = ((1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0))
    for q in range(64):
        for r, (sa, sb) in enumerate(signs):
            h = order[4 * q + r]
            tables[1, h] = sa * base[a_rows[q]]
            tables[2, h] = sb * base[b_rows[q]]
    return tables


def gradient_codes(table: np.ndarray, perm: np.ndarray) -> np.ndarray:
    """The gradients of `table` (256, C, D) (C <= 3, D <= 4; entries 0 or +-u, one u for the
    whole table, as every table of this module has) packed 2 bits an entry, and read through
    the permutation: (512,) int64, codes[x] = code[perm[x]] with bits 8 c + 2 k .. 8 c + 2 k + 1
    of code[h] holding table[h, c, k] / u + 1 (0, 1 or 2).

    3-D curl-noise, both kinds, reads these instead of the tables (``kernels.simplex_block``,
    ``kernels.perlin_block``): decoded in registers they need no gather, so the corner loop
    vectorises.
    """
    table = np.asarray(table, dtype=np.float64)
    if table.ndim != 3 or table.shape[0] != 256 or table.shape[1] > 3 or table.shape[2] > 4:
        raise ValueError(f"table must be (256, C <= 3, D <= 4); got {table.shape}")
    unit = np.abs(table).max()
    steps = np.rint(table / unit)
    if not np.array_equal(steps * unit, table):
        raise ValueError("table entries must all be 0 or +-u for one u")
    code = np.zeros(256, dtype=np.int64)
    for c in range(table.shape[1]):
        for k in range(table.shape[2]):
            code |= (steps[:, c, k].astype(np.int64) + 1) << (8 * c + 2 * k)
    # Entries a table lacks decode to 0 (code 1).
    for c in range(3):
        for k in range(4):
            if c >= table.shape[1] or k >= table.shape[2]:
                code |= np.int64(1) << (8 * c + 2 * k)
    return np.ascontiguousarray(code[np.asarray(perm, dtype=np.int64)])


@dataclass(frozen=True)
class NoiseParameters:
    """Validated fractal-noise parameters shared by ``Noise`` and ``CurlNoise``."""

    seed: int
    kind: str
    frequency: float
    octaves: int
    lacunarity: float
    gain: float
    amplitude: float
    time_frequency: float

    @classmethod
    def check(cls, *, seed, kind, frequency, octaves, lacunarity, gain, amplitude, time_frequency):
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {list(KINDS)}; got {kind!r}")
        if isinstance(octaves, bool) or not isinstance(octaves, numbers.Integral) or not 1 <= octaves <= 16:
            raise ValueError(f"octaves must be an integer in [1, 16]; got {octaves!r}")
        return cls(seed=int(seed), kind=kind,
                   frequency=positive_scalar(frequency, "frequency"),
                   octaves=int(octaves),
                   lacunarity=positive_scalar(lacunarity, "lacunarity"),
                   gain=positive_scalar(gain, "gain"),
                   amplitude=positive_scalar(amplitude, "amplitude", allow_zero=True),
                   time_frequency=positive_scalar(time_frequency, "time_frequency", allow_zero=True))

    @property
    def kind_code(self) -> int:
        return K.KIND_SIMPLEX if self.kind == "simplex" else K.KIND_PERLIN

    def scale(self, lattice_dim: int) -> float:
        """amplitude / (bound * sum_o gain^o): the factor that maps the raw sum into [-amp, amp]."""
        weights = sum(self.gain ** o for o in range(self.octaves))
        return self.amplitude / (_BOUND[(self.kind, lattice_dim)] * weights)


class Noise:
    """Seeded scalar gradient noise N(x, t) with fractal octaves and analytic derivatives.

    Parameters
    ----------
    dim : int
        Spatial dimension of the points: 2, 3 or 4 (4 only with ``time_frequency=0``; the
        lattice has ``dim + 1`` axes when time is an axis, at most 4).
    seed : int
        0 default; same seed gives the same field on every machine.
    kind : {"simplex", "perlin"}
        "simplex" default (Perlin 2001 / Gustavson): D + 1 corners, cheaper in 3-D and 4-D;
        "perlin" (Perlin 2002 improved noise): 2^D corners, a more axis-aligned look.
    frequency : float
        Lattice cells per unit length of the first octave; 1.0 default. Features are about
        half a cell across.
    octaves : int
        1 default; 1-8 (each octave costs one more noise evaluation).
    lacunarity : float
        Frequency ratio between octaves; 2.0 default (1.5-3).
    gain : float
        Amplitude ratio between octaves; 0.5 default (0.3-0.7; higher is rougher).
    amplitude : float
        Bound of |N|; 1.0 default. Values lie in [-amplitude, amplitude].
    time_frequency : float
        Lattice cells per second along the time axis of the first octave; 0.0 default (a
        frozen field); 0.1-1 for slowly evolving patterns. Octave o evolves lacunarity^o
        times faster.
    """

    def __init__(self, dim: int = 3, *, seed: int = 0, kind: str = "simplex",
                 frequency: float = 1.0, octaves: int = 1, lacunarity: float = 2.0,
                 gain: float = 0.5, amplitude: float = 1.0, time_frequency: float = 0.0):
        if dim not in (2, 3, 4):
            raise ValueError(f"dim must be one of [2, 3, 4]; got {dim!r}")
        self.params = NoiseParameters.check(
            seed=seed, kind=kind, frequency=frequency, octaves=octaves, lacunarity=lacunarity,
            gain=gain, amplitude=amplitude, time_frequency=time_frequency)
        self.dim = int(dim)
        self.lattice_dim = self.dim + (1 if self.params.time_frequency != 0.0 else 0)
        if self.lattice_dim > 4:
            raise ValueError("time_frequency must be 0 for dim=4 (the lattice has at most 4 axes); "
                             f"got {time_frequency!r}")
        self._perm, offsets = lattice_tables(self.params.seed, 1, self.params.octaves)
        self._offsets = np.ascontiguousarray(offsets[0])
        self._grads = _GRADIENTS[self.lattice_dim]
        self._scale = self.params.scale(self.lattice_dim)
        self._empty1 = np.empty((0, self.dim))
        self._empty2 = np.empty((0, self.dim, self.dim))

    @property
    def range(self) -> tuple[float, float]:
        """Guaranteed bounds of the values: (-amplitude, amplitude)."""
        return (-self.params.amplitude, self.params.amplitude)

    def __repr__(self):
        p = self.params
        return (f"Noise(dim={self.dim}, seed={p.seed}, kind={p.kind!r}, frequency={p.frequency}, "
                f"octaves={p.octaves}, amplitude={p.amplitude}, time_frequency={p.time_frequency})")

    # -- evaluation -------------------------------------------------------------------------
    def _run(self, points, t, value_out, grad_out, hess_out, order):
        p = self.params
        # One thread below K.SERIAL_BELOW elements (inertia._jit's size dispatch).
        K.fractal_noise(points, self._offsets, self._perm, self._grads, value_out, grad_out,
                        hess_out, float(t), p.kind_code, order, p.frequency, p.lacunarity, p.gain,
                        p.octaves, p.time_frequency, self._scale)

    def _points(self, points):
        return as_points(points, "points", dim=self.dim)

    def __call__(self, points, t: float = 0.0) -> np.ndarray:
        """Noise values at (M, dim) points: (M,) float64 in [-amplitude, amplitude]."""
        pts = self._points(points)
        out = np.empty(pts.shape[0])
        self._run(pts, t, out, self._empty1, self._empty2, 0)
        return out

    def sample(self, points: np.ndarray, t: float, out: np.ndarray) -> None:
        """Fill `out` (M,) with the noise at C-contiguous float64 `points` (M, dim)."""
        if out.shape != (points.shape[0],):
            raise ValueError(f"out must have shape ({points.shape[0]},); got {out.shape}")
        self._run(points, t, out, self._empty1, self._empty2, 0)

    def sample_with_gradient(self, points, t, value_out, gradient_out) -> None:
        """Fill value_out (M,) and gradient_out (M, dim) (dN/dx, analytic)."""
        if value_out.shape != (points.shape[0],) or gradient_out.shape != points.shape:
            raise ValueError(f"value_out must have shape ({points.shape[0]},) and gradient_out "
                             f"{points.shape}; got {value_out.shape} and {gradient_out.shape}")
        self._run(points, t, value_out, gradient_out, self._empty2, 1)

    def gradient(self, points, t: float = 0.0) -> np.ndarray:
        """Analytic spatial gradient dN/dx at each point: (M, dim)."""
        pts = self._points(points)
        value = np.empty(pts.shape[0])
        grad = np.empty_like(pts)
        self._run(pts, t, value, grad, self._empty2, 1)
        return grad

    def hessian(self, points, t: float = 0.0) -> np.ndarray:
        """Analytic spatial Hessian d2N/dx_a dx_b at each point: (M, dim, dim)."""
        pts = self._points(points)
        value = np.empty(pts.shape[0])
        grad = np.empty_like(pts)
        hess = np.empty((pts.shape[0], self.dim, self.dim))
        self._run(pts, t, value, grad, hess, 2)
        return hess
