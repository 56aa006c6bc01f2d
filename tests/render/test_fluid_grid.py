"""Colour-map images of 2-D grid fluids (inertia.render.fluid_grid)."""

import numpy as np
import pytest

from inertia.fluids.grid import GridFluid
from inertia.render.fluid_grid import FluidImage, side_by_side
from inertia.render.png import read_png


def _fluid():
    f = GridFluid((16, 8), 1 / 8, scalars=("density",), boundaries={s: "slip" for s in ("x-", "x+", "y-", "y+")})
    f.set_velocity(lambda p: np.stack([np.ones(len(p)), np.zeros(len(p))], 1))
    f.scalar("density")[12:, 6:] = 1.0  # a dense block at the top right
    return f


def test_density_image_orientation_size_and_png_round_trip(tmp_path):
    f = _fluid()
    img = FluidImage(f, "density", pixels_per_cell=3)
    a = img.image()
    assert a.shape == (8 * 3, 16 * 3, 3) and a.dtype == np.uint8
    # the dense block (x cells 12..15, y cells 6..7) is the top-right corner of the image
    top_right = a[:6, 36:].astype(int).sum(axis=2)
    bottom_left = a[-6:, :6].astype(int).sum(axis=2)
    assert top_right.min() > bottom_left.max()
    path = img.write(tmp_path / "d.png")
    assert np.array_equal(read_png(path)[..., :3], a)


def test_tracers_move_with_the_flow_and_streaks_are_drawn():
    f = _fluid()
    img = FluidImage(f, "speed", tracers=20, streak_length=4, seed=1)
    x0 = img.history[-1].copy()
    img.advance_tracers(0.1)
    moved = img.history[-1] - x0
    inside = (x0[:, 0] > 0.13) & (x0[:, 0] < 1.7)  # clear of the slip walls (u = 0 on x = 0, 2 m)
    assert inside.sum() > 10
    assert np.allclose(moved[inside], [0.1, 0.0], atol=1e-9)  # u = 1 m/s for 0.1 s
    a = img.image()
    assert (a.astype(int).sum(axis=2) >= 3 * 250).any()  # the newest streak dots are white


def test_vorticity_map_and_side_by_side_and_bad_input():
    f = _fluid()
    a = FluidImage(f, "vorticity").image()
    both = side_by_side([a, a], gap=2)
    assert both.shape == (a.shape[0], 2 * a.shape[1] + 2, 3)
    with pytest.raises(ValueError, match="quantity"):
        FluidImage(f, "pressure")
    with pytest.raises(ValueError, match="pixels_per_cell"):
        FluidImage(f, "density", pixels_per_cell=0)


# ----------------------------------------------------------------------------- streaks of recorded runs
from inertia.render.fluid_grid import STREAK_TAIL_ALPHA, GridStreaks, streak_alpha  # noqa: E402


def _cell_centres(nx, ny, h):
    x = (np.arange(nx) + 0.5) * h
    y = (np.arange(ny) + 0.5) * h
    return np.meshgrid(x, y, indexing="ij")


def _frames(u, v, frames):
    return (np.repeat(np.asarray(u, np.float32)[None], frames, 0), np.repeat(np.asarray(v, np.float32)[None], frames, 0))


def test_uniform_flow_streak_is_a_straight_segment_of_length_U_K_dt():
    # Closed form: in a uniform flow U every tracer moves by U dt a frame, so a streak of K frames
    # is the segment from x - U K dt to x. Drawn at 200 px/m its lit pixels lie within the
    # capsule of half-width w/2 + 1/2 (the anti-aliasing reach) around that segment, and they
    # span its length plus the two caps within one pixel.
    nx, ny, h, K, dt = 40, 20, 0.05, 8, 0.05
    U = np.array([0.6, 0.3])
    u, v = _frames(np.full((nx, ny), U[0]), np.full((nx, ny), U[1]), K + 1)
    s = GridStreaks(u, v, np.arange(K + 1) * dt, (0.0, 0.0), h, count=30, length=K, lifetime=0, seed=2)
    hist, valid = s.at(K)
    full = np.flatnonzero(valid == K + 1)
    assert full.size >= 10
    assert np.abs(hist[0, full] - hist[K, full] - U * K * dt).max() < 1e-6
    # every intermediate point is on the segment (straight) at equal spacing U dt
    assert np.abs(np.diff(hist[:, full], axis=0) + U * dt).max() < 1e-6

    m = full[0]
    scale, width = 200.0, 1.5
    alpha = np.zeros((200, 400), np.float32)
    one = np.ascontiguousarray(hist[:, m:m + 1])
    streak_alpha(one, np.array([K + 1]), 0.0, scale, 200.0, -scale, width, STREAK_TAIL_ALPHA, alpha)
    rows, cols = np.nonzero(alpha)
    centres = np.stack([cols + 0.5, rows + 0.5], axis=1)
    head = np.array([hist[0, m, 0] * scale, 200.0 - hist[0, m, 1] * scale])
    tail = np.array([hist[K, m, 0] * scale, 200.0 - hist[K, m, 1] * scale])
    d = (head - tail) / np.linalg.norm(head - tail)
    along = (centres - tail) @ d
    across = np.abs((centres - tail) @ np.array([-d[1], d[0]]))
    length_px = np.linalg.norm(U) * K * dt * scale
    reach = width / 2 + 0.5
    assert np.isclose(np.linalg.norm(head - tail), length_px, atol=1e-4)
    assert across.max() < reach
    assert -reach <= along.min() <= -reach + 1.0 and length_px + reach - 1.0 <= along.max() <= length_px + reach
    # the newest end is opaque, the oldest fades to the tail opacity
    a_head = alpha[int(head[1]), int(head[0])]
    a_tail = alpha[int(tail[1]), int(tail[0])]
    assert a_head > 0.9 and a_tail < STREAK_TAIL_ALPHA + 0.05


def test_solid_body_rotation_keeps_tracers_on_their_circles_within_the_rk2_bound():
    # u = omega x (x - c) is linear, so the bilinear cell-centre field is exact inside the cell
    # centres' box and the only error is RK2's: the midpoint rule's amplification on a rotation is
    # 1 - theta^2/2 + i theta (theta = omega h_s), so each substep multiplies the radius by
    # sqrt(1 + theta^4 / 4) and turns by atan2(theta, 1 - theta^2 / 2) (Hairer, Norsett and Wanner
    # 1993, II.1: the stability function of explicit RK2). Over N substeps the radius grows by
    # (1 + theta^4/4)^(N/2) - 1 = 1.8e-5 here; measured against that within the float32 rounding of
    # the recorded field (bound 1e-7, measured 1.2e-9).
    n, omega, dt, frames = 64, 2 * np.pi, 0.05, 16
    h = 1.0 / n
    x, y = _cell_centres(n, n, h)
    u, v = _frames(-omega * (y - 0.5), omega * (x - 0.5), frames)
    s = GridStreaks(u, v, np.arange(frames) * dt, (0.0, 0.0), h, count=200, length=frames - 1, lifetime=0, seed=5)
    hist, valid = s.at(frames - 1)
    sub = s.substeps(0, 1)
    steps = sub * (frames - 1)
    theta = omega * dt / sub
    p0, p1 = hist[-1] - 0.5, hist[0] - 0.5
    r0, r1 = np.hypot(*p0.T), np.hypot(*p1.T)
    keep = (valid == frames) & (r0 < 0.5 - h / 2) & (r0 > 0.05)
    assert keep.sum() > 100
    growth = (1 + theta**4 / 4) ** (steps / 2) - 1
    assert 1e-5 < growth < 1e-4                                  # the bound is not vacuous here
    assert np.abs(r1[keep] / r0[keep] - 1 - growth).max() < 1e-7
    turn = steps * np.arctan2(theta, 1 - theta**2 / 2)           # 3/4 of a turn less RK2's phase lag
    measured = np.mod(np.arctan2(p1[keep, 1], p1[keep, 0]) - np.arctan2(p0[keep, 1], p0[keep, 0]), 2 * np.pi)
    assert abs(turn - 1.5 * np.pi) > 1e-4 and np.abs(measured - turn).max() < 1e-5


def test_tracers_that_leave_or_enter_solids_are_reseeded_in_the_fluid():
    nx, ny, h, dt = 32, 16, 1 / 16, 0.05
    solid = np.zeros((nx, ny), np.uint8)
    solid[14:18, 4:12] = 1                                       # a block in the way of the flow
    u, v = _frames(np.full((nx, ny), 1.0), np.zeros((nx, ny)), 30)
    s = GridStreaks(u, v, np.arange(30) * dt, (0.0, 0.0), h, solid=np.repeat(solid[None], 30, 0),
                    count=300, length=6, lifetime=0, seed=1)
    x0 = s.at(0)[0][0].copy()
    for f in range(1, 30):
        hist, valid = s.at(f)
        cell = (hist[0] / h).astype(int)
        assert np.all((hist[0] >= 0) & (hist[0] <= [2.0, 1.0]))
        assert not solid[cell[:, 0], cell[:, 1]].any()
    cell0 = (x0 / h).astype(int)
    assert not solid[cell0[:, 0], cell0[:, 1]].any()
    assert (valid < 7).any()                                      # some streaks restarted
    with pytest.raises(ValueError, match="count"):
        GridStreaks(u, v, np.arange(30) * dt, (0.0, 0.0), h, count=0)
    with pytest.raises(ValueError, match="frame"):
        s.at(30)


def test_streaks_are_the_same_bit_for_bit_and_after_a_jump_back():
    nx, ny, h = 24, 24, 1 / 24
    x, y = _cell_centres(nx, ny, h)
    u, v = _frames(-(y - 0.5) * 3.0, (x - 0.5) * 3.0 + 0.2, 12)
    times = np.arange(12) * 0.05

    def image(s, f):
        img = np.zeros((96, 96, 3), np.uint8)
        s.paint(img, f, (0.0, 96.0, 96.0, -96.0))
        return img

    a = GridStreaks(u, v, times, (0.0, 0.0), h, count=100, seed=4)
    b = GridStreaks(u, v, times, (0.0, 0.0), h, count=100, seed=4)
    first = image(a, 9)
    assert np.array_equal(first, image(b, 9)) and first.any()
    image(a, 11)
    assert np.array_equal(image(a, 9), first)                    # back in time: replayed from frame 0
    assert not np.array_equal(image(GridStreaks(u, v, times, (0.0, 0.0), h, count=100, seed=5), 9), first)


def test_grid_fluid_records_cell_centre_velocity_and_solid_cells():
    import inertia as ia

    ball = ia.colliders.Sphere(center=(0.5, 0.5), radius=0.2)
    f = GridFluid((16, 16), 1 / 16, obstacles=[ball], scalars=())
    f.set_velocity(lambda p: np.stack([p[:, 1], -p[:, 0]], 1))
    a = f.frame_arrays()
    assert a["u"].dtype == np.float32 and a["u"].shape == (16, 16) and a["solid"].dtype == np.uint8
    assert np.allclose(a["u"], 0.5 * (f.u[1:] + f.u[:-1]), atol=1e-6)
    assert np.allclose(a["v"], 0.5 * (f.v[:, 1:] + f.v[:, :-1]), atol=1e-6)
    x, y = _cell_centres(16, 16, 1 / 16)
    assert np.array_equal(a["solid"] == 1, np.hypot(x - 0.5, y - 0.5) < 0.2)
    with pytest.raises(ValueError, match="scalars"):
        GridFluid((8, 8), 1 / 8, scalars=("u",))
