import textwrap

import pytest


@pytest.fixture
def write_scene(tmp_path):
    """write_scene(text, name="scene.toml") -> path of a scene file in a temporary directory."""
    def write(text: str, name: str = "scene.toml"):
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path
    return write
