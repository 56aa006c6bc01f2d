"""The web viewer: its controls from Python, and a real headless Chromium showing the scene."""

from __future__ import annotations

import contextlib
import shutil
import tempfile
import time

import numpy as np
import pytest

pytest.importorskip("viser")

from inertia.io import States  # noqa: E402
from inertia.viewer import view  # noqa: E402

pytestmark = pytest.mark.timeout(240)


def _run(frames=6, n=150):
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.normal(size=(frames, n, 3)) * 0.02, axis=0) + rng.random((1, n, 3))
    return States(times=np.arange(frames) / 10.0, positions=x, velocities=np.zeros_like(x),
                  static={"radius": np.full(n, 0.03)}, metadata={"fps": 10.0})


def test_controls_step_scrub_loop_and_live_sources():
    import inertia.colliders as C

    moving = C.Sphere(center=(0.0, 0.0, 0.0), radius=0.2, motion=C.Motion(position=lambda t: (t, 0.0, 0.5)))
    viewer = view(_run(), port=0, block=False, autoplay=False, colliders=[C.Plane(), moving])
    try:
        assert viewer.url.startswith("http://127.0.0.1:") and viewer.port > 0
        viewer.set_frame(3)
        assert viewer.frame == 3 and "frame 3 / 5" in viewer._time_text.content
        viewer.set_frame(99)  # clamped
        assert viewer.frame == 5
        viewer.step()  # loops to the start
        assert viewer.frame == 0
        viewer.loop = False
        viewer.set_frame(5)
        viewer.play()
        viewer.step()
        assert viewer.frame == 5 and not viewer.playing
        viewer.fps = 200.0
        viewer.play()
        time.sleep(0.3)
        viewer.pause()
    finally:
        viewer.close()

    # Live: a callback stepping a "simulation" once per shown frame.
    state = {"x": np.zeros((10, 2))}

    def advance():
        state["x"] = state["x"] + 0.1
        return state["x"], np.ones((10, 2))

    live = view(advance, port=0, block=False, autoplay=False, dim=2)
    try:
        live.step()
        live.step()
        assert live.frame == 2
        np.testing.assert_allclose(state["x"], 0.3)
    finally:
        live.close()


def _chromium():
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    return browser, driver


def _sph_run(frames=4):
    """A 2-D SPH fluid as a run records it (fluid/<name>/x, v, active; the fluid's spacing), and no
    particle group: worlds without groups record 3-D positions of zero particles."""
    g = np.arange(0.0, 0.5, 0.02)
    x, y = np.meshgrid(g, g, indexing="ij")
    block = np.column_stack([x.ravel(), y.ravel()]).astype(np.float32)
    fx = np.stack([block + np.float32(0.01 * f) for f in range(frames)])
    fields = {"fluid/water/x": fx, "fluid/water/v": np.ones_like(fx),
              "fluid/water/active": np.ones(fx.shape[:2], bool)}
    return States(times=np.arange(frames) / 10.0, positions=np.zeros((frames, 0, 3)), fields=fields,
                  metadata={"fps": 10.0, "fluids": ["water"]}, model={"fluid/water/spacing": np.array([0.02])})


def _smoke_run(frames=3, n=16):
    """A 3-D smoke grid as a run records it: fluid/<name>/density and speed (F, nx, ny, nz), origin
    and cell size in the model; a ball of density in the middle."""
    c = (np.arange(n) + 0.5) / n - 0.5
    r2 = c[:, None, None] ** 2 + c[None, :, None] ** 2 + c[None, None, :] ** 2
    density = np.stack([np.clip(1.0 - r2 / 0.12, 0.0, None) * (1 + 0.1 * f) for f in range(frames)]).astype(np.float32)
    fields = {"fluid/smoke/density": density, "fluid/smoke/speed": density * 0.5}
    return States(times=np.arange(frames) / 10.0, positions=np.zeros((frames, 0, 3)), fields=fields,
                  metadata={"fps": 10.0, "fluids": ["smoke"]},
                  model={"fluid/smoke/origin": np.zeros(3), "fluid/smoke/cell_size": np.array(1.0 / n)})


def test_fluids_are_shown():
    """SPH particles become the viewer's particles in the fluid's own (2-D) plane; a 3-D smoke grid
    a cloud of its dense cells, updated with the frame."""
    viewer = view(_sph_run(), port=0, block=False, autoplay=False)
    try:
        assert viewer.dim == 2 and viewer._particle_count == 625
    finally:
        viewer.close()
    viewer = view(_smoke_run(), port=0, block=False, autoplay=False)
    try:
        cloud = viewer._grids.handles["smoke"]
        first = np.asarray(cloud.points).shape[0]
        assert viewer.dim == 3 and first > 500  # a ball of radius ~0.35 of 16^3 cells above 5 % density
        viewer.set_frame(2)
        assert viewer._grids.handles["smoke"] is not cloud
    finally:
        viewer.close()


@contextlib.contextmanager
def _in_chromium(viewer, count_pixels, needed: int, seconds: float = 90.0):
    """Open the viewer in headless Chromium; yield (driver, pixels) once a screenshot has ``needed``
    pixels that ``count_pixels(rgb)`` counts (or the deadline passed); then close the browser, the
    viewer and the browser's profile folder."""
    webdriver = pytest.importorskip("selenium.webdriver")
    from selenium.webdriver.chrome.service import Service

    from inertia.render import read_png

    browser, driver_path = _chromium()
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    profile = tempfile.mkdtemp(prefix="inertia-chromium-")
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--window-size=1200,800",
                 f"--user-data-dir={profile}"):
        options.add_argument(flag)
    driver = None
    try:
        driver = webdriver.Chrome(service=Service(driver_path), options=options)
        driver.set_page_load_timeout(60)
        driver.get(viewer.url)
        shot = tempfile.mktemp(suffix=".png")
        found = 0
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            time.sleep(2.0)
            try:
                driver.save_screenshot(shot)
            except Exception:  # noqa: BLE001 - the renderer may be busy; try again
                continue
            found = count_pixels(read_png(shot)[..., :3].astype(int))
            if found > needed:
                break
        yield driver, found
    finally:
        if driver is not None:
            driver.quit()
        viewer.close()
        shutil.rmtree(profile, ignore_errors=True)


def _magenta(p):
    return int(((p[..., 0] > 120) & (p[..., 2] > 120) & (p[..., 1] < 90)).sum())


def _warm(p):  # the inferno map's orange-to-yellow half (dense smoke), not the page's greys
    return int(((p[..., 0] > 150) & (p[..., 0] - p[..., 2] > 90)).sum())


@pytest.mark.skipif(None in _chromium(), reason="needs Chromium and ChromeDriver (apt-get install chromium chromium-driver)")
@pytest.mark.parametrize("kind", ["sph", "smoke"])
def test_headless_chromium_shows_the_fluids(kind):
    if kind == "sph":
        viewer = view(_sph_run(), port=0, block=False, autoplay=False, color_by="uniform", color=(1.0, 0.0, 1.0))
        count = _magenta
    else:
        viewer = view(_smoke_run(), port=0, block=False, autoplay=False)
        count = _warm
    with _in_chromium(viewer, count, 2000) as (driver, found):
        assert found > 2000, f"the screenshot shows no {kind} ({found} pixels)"


@pytest.mark.skipif(None in _chromium(), reason="needs Chromium and ChromeDriver (apt-get install chromium chromium-driver)")
def test_headless_chromium_shows_the_particles_and_steps():
    By = pytest.importorskip("selenium.webdriver.common.by").By

    viewer = view(_run(), port=0, block=False, autoplay=False, color_by="uniform", color=(1.0, 0.0, 1.0))
    # Wait until the WebGL canvas shows magenta particles (software GL: give it time).
    with _in_chromium(viewer, _magenta, 2000) as (driver, magenta):
        assert magenta > 2000, f"the screenshot shows no particles ({magenta} magenta pixels)"
        # The Step button advances the frame shown in the panel.
        step = driver.find_element(By.XPATH, "//button[normalize-space()='Step']")
        step.click()
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and "frame 1 / 5" not in driver.page_source:
            time.sleep(0.5)
        assert "frame 1 / 5" in driver.page_source
        assert viewer.frame == 1


def test_rigid_bodies_are_meshes_moved_by_body_q():
    # A box on body 0 and a sphere fixed in the world (body -1); body 0 moves along x and turns
    # about z: its mesh handle follows the body pose composed with the shape's local offset.
    frames = 4
    xs = np.linspace(0.0, 1.5, frames)
    angle = np.linspace(0.0, np.pi / 2, frames)
    body_q = np.zeros((frames, 1, 7))
    body_q[:, 0, 0] = xs
    body_q[:, 0, 3], body_q[:, 0, 6] = np.cos(angle / 2), np.sin(angle / 2)
    states = _run(frames, n=20)
    states.fields["body_q"] = body_q
    states.model = {  # the contract's States.model
        "shape_type": np.array([1, 0], np.int32), "shape_body": np.array([0, -1], np.int32),
        "shape_local_pose": np.array([[0.2, 0.0, 0.0, 1.0, 0, 0, 0], [0.0, 1.0, 0.5, 1.0, 0, 0, 0]]),
        "shape_params": np.array([[0.1, 0.2, 0.3, 0.0], [0.25, 0.0, 0.0, 0.0]]),
    }
    viewer = view(states, port=0, block=False, autoplay=False)
    try:
        assert len(viewer._body_handles) == 1  # the static sphere is drawn once, not moved
        handle, row = viewer._body_handles[0]
        viewer.set_frame(3)
        # Body at x = 1.5 turned 90 degrees: the local offset (0.2, 0, 0) points along +y.
        assert np.allclose(handle.position, (1.5, 0.2, 0.0), atol=1e-6)
        assert np.allclose(np.abs(handle.wxyz), (np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)), atol=1e-6)
        viewer.set_frame(0)
        assert np.allclose(handle.position, (0.2, 0.0, 0.0), atol=1e-6)
    finally:
        viewer.close()
