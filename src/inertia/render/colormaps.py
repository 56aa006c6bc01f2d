"""Colour maps and palettes for particles: perceptual maps for scalars, a categorical palette for groups.

The scalar maps are the matplotlib maps viridis, magma, plasma, inferno, cividis (van der Walt &
Smith 2015, CC0), turbo (Mikhailov 2019, Apache-2.0) and coolwarm (Moreland 2009), tabulated at 33
evenly spaced points and interpolated linearly, which reproduces them within about 5/255
without importing matplotlib. The group palette is Tableau 10 (as matplotlib's ``tab10``).

References
----------
van der Walt, S. & Smith, N. (2015). "A Better Default Colormap for Matplotlib", SciPy 2015.
Moreland, K. (2009). "Diverging Color Maps for Scientific Visualization", ISVC 2009.
Mikhailov, A. (2019). "Turbo, An Improved Rainbow Colormap for Visualization", Google AI blog.

All colours are sRGB floats in [0, 1]; `colormap` returns (M, 3) float32.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "COLORMAPS", "GROUP_PALETTE", "colormap", "group_colors", "group_palette", "speed_colors", "parse_color",
    "particle_colors", "resolve_color_mode", "robust_speed_max", "run_speed_max", "DEFAULT_SPEED_MAP",
]

_TABLES = {
    "viridis": (
        (0.2670, 0.0049, 0.3294), (0.2770, 0.0503, 0.3757), (0.2823, 0.0950, 0.4173), (0.2829, 0.1359, 0.4534),
        (0.2788, 0.1755, 0.4834), (0.2706, 0.2141, 0.5071), (0.2590, 0.2515, 0.5247), (0.2450, 0.2877, 0.5373),
        (0.2297, 0.3224, 0.5457), (0.2143, 0.3556, 0.5512), (0.1994, 0.3876, 0.5546), (0.1856, 0.4186, 0.5568),
        (0.1727, 0.4488, 0.5579), (0.1607, 0.4785, 0.5581), (0.1490, 0.5081, 0.5573), (0.1378, 0.5375, 0.5549),
        (0.1276, 0.5669, 0.5506), (0.1206, 0.5964, 0.5436), (0.1206, 0.6258, 0.5335), (0.1323, 0.6550, 0.5197),
        (0.1579, 0.6838, 0.5017), (0.1966, 0.7118, 0.4792), (0.2461, 0.7389, 0.4520), (0.3041, 0.7647, 0.4199),
        (0.3692, 0.7889, 0.3829), (0.4401, 0.8111, 0.3410), (0.5160, 0.8312, 0.2943), (0.5958, 0.8487, 0.2433),
        (0.6785, 0.8637, 0.1895), (0.7624, 0.8764, 0.1371), (0.8456, 0.8873, 0.0997), (0.9261, 0.8973, 0.1041),
        (0.9932, 0.9062, 0.1439),
    ),
    "magma": (
        (0.0015, 0.0005, 0.0139), (0.0137, 0.0118, 0.0687), (0.0396, 0.0311, 0.1335), (0.0743, 0.0520, 0.2027),
        (0.1131, 0.0655, 0.2768), (0.1590, 0.0684, 0.3527), (0.2117, 0.0620, 0.4186), (0.2654, 0.0602, 0.4618),
        (0.3167, 0.0717, 0.4854), (0.3660, 0.0903, 0.4980), (0.4147, 0.1104, 0.5047), (0.4635, 0.1299, 0.5077),
        (0.5128, 0.1482, 0.5076), (0.5629, 0.1654, 0.5047), (0.6136, 0.1818, 0.4985), (0.6649, 0.1981, 0.4888),
        (0.7164, 0.2150, 0.4753), (0.7674, 0.2337, 0.4578), (0.8169, 0.2559, 0.4365), (0.8633, 0.2837, 0.4124),
        (0.9043, 0.3196, 0.3881), (0.9372, 0.3649, 0.3686), (0.9609, 0.4183, 0.3596), (0.9767, 0.4762, 0.3645),
        (0.9867, 0.5356, 0.3822), (0.9928, 0.5949, 0.4103), (0.9961, 0.6537, 0.4462), (0.9973, 0.7118, 0.4882),
        (0.9969, 0.7696, 0.5349), (0.9951, 0.8271, 0.5857), (0.9924, 0.8843, 0.6401), (0.9894, 0.9415, 0.6975),
        (0.9871, 0.9914, 0.7495),
    ),
    "plasma": (
        (0.0504, 0.0298, 0.5280), (0.1324, 0.0223, 0.5633), (0.1934, 0.0184, 0.5903), (0.2480, 0.0144, 0.6129),
        (0.2999, 0.0096, 0.6316), (0.3502, 0.0044, 0.6463), (0.3994, 0.0009, 0.6561), (0.4477, 0.0021, 0.6602),
        (0.4949, 0.0120, 0.6579), (0.5406, 0.0350, 0.6486), (0.5844, 0.0686, 0.6328), (0.6260, 0.1033, 0.6113),
        (0.6651, 0.1386, 0.5856), (0.7018, 0.1740, 0.5573), (0.7360, 0.2094, 0.5279), (0.7681, 0.2448, 0.4985),
        (0.7982, 0.2802, 0.4695), (0.8266, 0.3157, 0.4413), (0.8533, 0.3516, 0.4137), (0.8784, 0.3879, 0.3866),
        (0.9018, 0.4251, 0.3597), (0.9233, 0.4633, 0.3328), (0.9426, 0.5026, 0.3058), (0.9594, 0.5434, 0.2787),
        (0.9734, 0.5858, 0.2515), (0.9842, 0.6297, 0.2246), (0.9914, 0.6754, 0.1985), (0.9945, 0.7227, 0.1744),
        (0.9930, 0.7717, 0.1548), (0.9865, 0.8224, 0.1436), (0.9744, 0.8746, 0.1441), (0.9568, 0.9282, 0.1524),
        (0.9400, 0.9752, 0.1313),
    ),
    "inferno": (
        (0.0015, 0.0005, 0.0139), (0.0140, 0.0112, 0.0719), (0.0423, 0.0281, 0.1411), (0.0820, 0.0433, 0.2153),
        (0.1293, 0.0473, 0.2908), (0.1834, 0.0403, 0.3550), (0.2383, 0.0366, 0.3964), (0.2908, 0.0456, 0.4186),
        (0.3415, 0.0623, 0.4294), (0.3915, 0.0809, 0.4331), (0.4412, 0.0993, 0.4316), (0.4910, 0.1172, 0.4256),
        (0.5409, 0.1347, 0.4151), (0.5907, 0.1526, 0.4003), (0.6401, 0.1714, 0.3811), (0.6887, 0.1922, 0.3576),
        (0.7357, 0.2159, 0.3302), (0.7805, 0.2433, 0.2995), (0.8224, 0.2752, 0.2661), (0.8605, 0.3119, 0.2306),
        (0.8943, 0.3534, 0.1936), (0.9232, 0.3994, 0.1552), (0.9470, 0.4492, 0.1153), (0.9654, 0.5022, 0.0739),
        (0.9784, 0.5579, 0.0349), (0.9860, 0.6158, 0.0256), (0.9879, 0.6753, 0.0653), (0.9841, 0.7361, 0.1295),
        (0.9746, 0.7977, 0.2063), (0.9606, 0.8591, 0.2980), (0.9476, 0.9174, 0.4107), (0.9545, 0.9659, 0.5404),
        (0.9884, 0.9984, 0.6449),
    ),
    "turbo": (
        (0.1900, 0.0718, 0.2322), (0.2250, 0.1635, 0.4510), (0.2511, 0.2524, 0.6337), (0.2682, 0.3382, 0.7805),
        (0.2763, 0.4212, 0.8912), (0.2754, 0.5011, 0.9659), (0.2586, 0.5796, 0.9988), (0.2138, 0.6589, 0.9796),
        (0.1584, 0.7355, 0.9231), (0.1117, 0.8057, 0.8452), (0.0927, 0.8655, 0.7623), (0.1201, 0.9119, 0.6866),
        (0.1966, 0.9490, 0.5947), (0.3051, 0.9770, 0.4899), (0.4278, 0.9942, 0.3857), (0.5466, 0.9991, 0.2958),
        (0.6436, 0.9900, 0.2336), (0.7260, 0.9647, 0.2064), (0.8047, 0.9245, 0.2046), (0.8753, 0.8727, 0.2155),
        (0.9330, 0.8124, 0.2267), (0.9732, 0.7468, 0.2254), (0.9931, 0.6741, 0.2035), (0.9959, 0.5870, 0.1690),
        (0.9836, 0.4929, 0.1285), (0.9580, 0.3996, 0.0883), (0.9211, 0.3149, 0.0548), (0.8742, 0.2453, 0.0330),
        (0.8161, 0.1846, 0.0181), (0.7462, 0.1310, 0.0085), (0.6645, 0.0844, 0.0042), (0.5710, 0.0447, 0.0053),
        (0.4796, 0.0158, 0.0106),
    ),
    "cividis": (
        (0.0000, 0.1351, 0.3048), (0.0000, 0.1579, 0.3575), (0.0000, 0.1788, 0.4148), (0.0179, 0.1985, 0.4412),
        (0.1034, 0.2204, 0.4358), (0.1543, 0.2425, 0.4301), (0.1951, 0.2644, 0.4259), (0.2309, 0.2861, 0.4235),
        (0.2637, 0.3078, 0.4228), (0.2947, 0.3295, 0.4237), (0.3242, 0.3513, 0.4263), (0.3529, 0.3732, 0.4302),
        (0.3808, 0.3952, 0.4357), (0.4082, 0.4174, 0.4426), (0.4352, 0.4398, 0.4511), (0.4616, 0.4624, 0.4620),
        (0.4887, 0.4853, 0.4710), (0.5179, 0.5085, 0.4727), (0.5478, 0.5319, 0.4717), (0.5782, 0.5557, 0.4687),
        (0.6091, 0.5798, 0.4636), (0.6404, 0.6044, 0.4568), (0.6720, 0.6293, 0.4480), (0.7040, 0.6547, 0.4371),
        (0.7365, 0.6806, 0.4240), (0.7694, 0.7070, 0.4085), (0.8027, 0.7340, 0.3902), (0.8364, 0.7615, 0.3687),
        (0.8707, 0.7896, 0.3433), (0.9056, 0.8183, 0.3129), (0.9411, 0.8475, 0.2758), (0.9778, 0.8773, 0.2280),
        (0.9957, 0.9093, 0.2178),
    ),
    "coolwarm": (
        (0.2298, 0.2987, 0.7537), (0.2664, 0.3533, 0.8016), (0.3042, 0.4069, 0.8453), (0.3433, 0.4594, 0.8841),
        (0.3837, 0.5102, 0.9178), (0.4252, 0.5591, 0.9461), (0.4677, 0.6056, 0.9685), (0.5108, 0.6494, 0.9851),
        (0.5543, 0.6901, 0.9955), (0.5978, 0.7273, 0.9998), (0.6408, 0.7608, 0.9978), (0.6831, 0.7900, 0.9898),
        (0.7240, 0.8149, 0.9757), (0.7634, 0.8351, 0.9557), (0.8006, 0.8504, 0.9300), (0.8353, 0.8605, 0.8990),
        (0.8674, 0.8644, 0.8626), (0.8995, 0.8475, 0.8178), (0.9256, 0.8255, 0.7711), (0.9455, 0.7986, 0.7231),
        (0.9595, 0.7670, 0.6741), (0.9675, 0.7308, 0.6247), (0.9697, 0.6905, 0.5751), (0.9660, 0.6461, 0.5259),
        (0.9567, 0.5980, 0.4773), (0.9417, 0.5464, 0.4297), (0.9214, 0.4914, 0.3834), (0.8959, 0.4331, 0.3387),
        (0.8654, 0.3711, 0.2958), (0.8302, 0.3047, 0.2549), (0.7906, 0.2314, 0.2162), (0.7468, 0.1400, 0.1800),
        (0.7057, 0.0156, 0.1502),
    ),
}


def _resampled(name: str, lo: float, hi: float, count: int = 33) -> tuple:
    """The map ``name`` between ``lo`` and ``hi`` (fractions of its range), as a new table."""
    table = np.asarray(_TABLES[name], dtype=np.float64)
    s = np.linspace(lo, hi, count) * (len(table) - 1)
    i = np.minimum(s.astype(np.int64), len(table) - 2)
    w = (s - i)[:, None]
    return tuple(map(tuple, np.round((1.0 - w) * table[i] + w * table[i + 1], 4)))


# "speed": turbo between 0.1 and 0.9 of its range, the default for speed colouring: bright from
# end to end (resting particles light blue, fast ones orange-red), so particles at rest stay
# readable on the dark theme's grey ground; viridis and the others start near black.
_TABLES["speed"] = _resampled("turbo", 0.1, 0.9)

#: The map `Renderer`, the viewer and `inertia run` use for speed colours unless told otherwise.
DEFAULT_SPEED_MAP = "speed"

#: Names accepted by `colormap`.
COLORMAPS = tuple(sorted(_TABLES))

#: Tableau 10: the categorical colours of particle groups, in order.
GROUP_PALETTE = np.array(
    [
        (0.1216, 0.4667, 0.7059), (1.0000, 0.4980, 0.0549), (0.1725, 0.6275, 0.1725), (0.8392, 0.1529, 0.1569),
        (0.5804, 0.4039, 0.7412), (0.5490, 0.3373, 0.2941), (0.8902, 0.4667, 0.7608), (0.4980, 0.4980, 0.4980),
        (0.7373, 0.7412, 0.1333), (0.0902, 0.7451, 0.8118),
    ],
    dtype=np.float32,
)

_NAMED = {
    "white": (1.0, 1.0, 1.0), "black": (0.0, 0.0, 0.0), "grey": (0.5, 0.5, 0.5), "gray": (0.5, 0.5, 0.5),
    "red": (0.8392, 0.1529, 0.1569), "green": (0.1725, 0.6275, 0.1725), "blue": (0.1216, 0.4667, 0.7059),
    "orange": (1.0, 0.498, 0.0549), "purple": (0.5804, 0.4039, 0.7412), "cyan": (0.0902, 0.7451, 0.8118),
    "yellow": (0.9882, 0.8, 0.1), "pink": (0.8902, 0.4667, 0.7608), "brown": (0.549, 0.3373, 0.2941),
}


def colormap(name: str, values: np.ndarray, *, vmin: float | None = None, vmax: float | None = None) -> np.ndarray:
    """Map scalars to sRGB colours (M, 3) float32 through the map ``name`` (see `COLORMAPS`).

    ``vmin``/``vmax`` default to the values' min and max; values outside are clamped;
    non-finite values map to the low end.
    """
    if name not in _TABLES:
        raise ValueError(f"colormap: unknown map {name!r}; choose one of {', '.join(COLORMAPS)}")
    table = np.asarray(_TABLES[name], dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    lo = float(np.min(values[finite])) if vmin is None and finite.any() else float(vmin or 0.0)
    hi = float(np.max(values[finite])) if vmax is None and finite.any() else float(1.0 if vmax is None else vmax)
    span = hi - lo if hi > lo else 1.0
    s = np.clip(np.where(finite, (values - lo) / span, 0.0), 0.0, 1.0) * (len(table) - 1)
    i = np.minimum(s.astype(np.int64), len(table) - 2)
    w = (s - i)[..., None]
    return ((1.0 - w) * table[i] + w * table[i + 1]).astype(np.float32)


def group_colors(groups: np.ndarray) -> np.ndarray:
    """Colour (M, 3) float32 of each particle's group index, cycling through `GROUP_PALETTE`."""
    groups = np.asarray(groups, dtype=np.int64)
    return GROUP_PALETTE[np.mod(groups, len(GROUP_PALETTE))]


def speed_colors(velocities: np.ndarray, *, vmax: float | None = None, cmap: str = DEFAULT_SPEED_MAP) -> np.ndarray:
    """Colour by speed |v|, from 0 to ``vmax`` (default: the 99th percentile of the speeds)."""
    speed = np.sqrt(np.einsum("ij,ij->i", velocities, velocities)) if len(velocities) else np.zeros(0)
    if vmax is None:
        vmax = float(np.percentile(speed, 99.0)) if speed.size else 1.0
    return colormap(cmap, speed, vmin=0.0, vmax=vmax if vmax > 0 else 1.0)


def parse_color(color) -> np.ndarray:
    """One colour as (3,) float32 sRGB in [0, 1], from a name, ``"#rrggbb"``, floats or 0-255 ints."""
    if isinstance(color, str):
        text = color.strip().lower()
        if text in _NAMED:
            return np.array(_NAMED[text], dtype=np.float32)
        if text.startswith("#") and len(text) == 7:
            return np.array([int(text[i : i + 2], 16) / 255.0 for i in (1, 3, 5)], dtype=np.float32)
        raise ValueError(f"unknown colour {color!r}: use a name ({', '.join(sorted(_NAMED))}), '#rrggbb' or an RGB triple")
    rgb = np.asarray(color)
    if rgb.shape != (3,):
        raise ValueError(f"a colour must be 3 numbers, got shape {rgb.shape}")
    if rgb.dtype.kind in "iu" or rgb.max() > 1.0:
        return (rgb.astype(np.float32) / 255.0).clip(0, 1)
    return rgb.astype(np.float32).clip(0, 1)


def group_palette(group_colors=None, count: int | None = None) -> np.ndarray:
    """(G, 3) float32 colours of groups: `GROUP_PALETTE` cycled, with the entries of
    ``group_colors`` (a list of colours or None per group, e.g. a state file's
    ``metadata["group_colors"]``) where given."""
    names = list(group_colors or [])
    size = max(len(names), count or 0, 1)
    palette = GROUP_PALETTE[np.arange(size) % len(GROUP_PALETTE)].copy()
    for i, name in enumerate(names):
        if name is not None and name != "":
            palette[i] = parse_color(name)
    return palette


def particle_colors(
    count: int,
    *,
    colors=None,
    velocities=None,
    groups=None,
    color_by: str = "auto",
    cmap: str = DEFAULT_SPEED_MAP,
    speed_max: float | None = None,
    color=(0.35, 0.62, 0.95),
    group_colors=None,
) -> np.ndarray:
    """sRGB colours (N, 3) float32 of particles, as the renderer and the viewer draw them.

    ``colors`` ((N, 3) floats or uint8, or one colour) wins; else ``color_by``: "speed" (|v|
    through ``cmap`` from 0 to ``speed_max``, default the 99th percentile), "group" (by group
    index through `group_palette`), "uniform" (``color``), or "auto": group when there are
    several groups, else speed when velocities are given, else uniform.
    """
    mode = resolve_color_mode(color_by, colors, velocities, groups)
    if mode == "explicit":
        c = parse_color(colors) if isinstance(colors, str) else np.asarray(colors)
        if c.shape == (3,):
            return np.broadcast_to(parse_color(c), (count, 3)).astype(np.float32)
        if c.shape != (count, 3):
            raise ValueError(f"colors must be ({count}, 3) or one colour, got shape {c.shape}")
        return (c.astype(np.float32) / 255.0) if c.dtype == np.uint8 else np.clip(c, 0, 1).astype(np.float32)
    if mode == "group":
        g = np.asarray(groups, dtype=np.int64)
        palette = group_palette(group_colors, int(g.max()) + 1 if g.size else 1)
        return palette[np.mod(g, len(palette))]
    if mode == "speed":
        v = np.asarray(velocities, dtype=np.float64)
        speed = np.sqrt(np.einsum("ij,ij->i", v, v)) if v.size else np.zeros(count)
        return colormap(cmap, speed, vmin=0.0, vmax=robust_speed_max(v) if speed_max is None else speed_max)
    return np.broadcast_to(parse_color(color), (count, 3)).astype(np.float32)


def resolve_color_mode(color_by: str, colors=None, velocities=None, groups=None) -> str:
    """"explicit", "group", "speed" or "uniform": what `particle_colors` will do."""
    if colors is not None:
        return "explicit"
    if color_by == "auto":
        if groups is not None and np.unique(np.asarray(groups)).size > 1:
            return "group"
        return "speed" if velocities is not None else "uniform"
    if (color_by == "group" and groups is None) or (color_by == "speed" and velocities is None):
        return "uniform"
    if color_by not in ("group", "speed", "uniform"):
        raise ValueError(f"color_by must be 'auto', 'speed', 'group' or 'uniform', got {color_by!r}")
    return color_by


def robust_speed_max(velocities) -> float:
    """The 99th percentile of |v| (1.0 when there is no positive finite speed)."""
    v = np.asarray(velocities, dtype=np.float64).reshape(-1, np.shape(velocities)[-1] if np.ndim(velocities) else 1)
    speed = np.sqrt(np.einsum("ij,ij->i", v, v))
    speed = speed[np.isfinite(speed)]
    vmax = float(np.percentile(speed, 99.0)) if speed.size else 1.0
    return vmax if vmax > 0 else 1.0


def run_speed_max(velocities) -> float:
    """One speed scale for a whole run: `robust_speed_max` over at most 50 frames of the
    (F, N, D) velocities, evenly spaced. The video and the viewer both colour by it, so a
    colour means the same speed in every frame and in both."""
    v = np.asarray(velocities)
    if v.ndim == 3:
        v = v[:: max(1, v.shape[0] // 50)]
    return robust_speed_max(v)
