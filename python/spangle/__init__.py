"""Spangle, an offline physically based renderer for glitter, from Python.

    import spangle
    s = spangle.Session()
    s.load("assets/scenes/beetle.toml")
    img = s.render(spp=16, size=(640, 360))
    img.beauty          # numpy float32, H x W x 3, the scene's working space
    img.layers["glints"]
    s.write(img, "beetle.exr")

See docs/python.md.
"""

import os as _os

from . import _spangle

_spangle._set_module_location(_os.path.dirname(_os.path.abspath(__file__)))

from ._spangle import Image, SceneError, Session, __version__  # noqa: E402

__all__ = ["Image", "SceneError", "Session", "__version__"]
