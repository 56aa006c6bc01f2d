"""Interactive web viewer (viser): play, pause, step, scrub time, orbit the camera.

Public API::

    view(states_or_path_or_callback, *, colliders=(), port=8080, host="127.0.0.1", fps=None,
         color_by="auto", open_browser=False, block=True, autoplay=True, **options) -> Viewer
    Viewer: .url, .port, .set_frame(i), .step(), .play(), .pause(), .wait(), .close()

Requires viser (``pip install inertia[viewer]``); imported on first use.
"""

from __future__ import annotations

__all__ = ["view", "Viewer"]


def __getattr__(name):
    if name in __all__:
        from . import app

        return getattr(app, name)
    raise AttributeError(f"module 'inertia.viewer' has no attribute {name!r}")
