"""inkwarp: animate a still image by animating a drawing traced over it.

The grid thin plate of Litwinowicz & Williams ("Animating Images with Drawings",
SIGGRAPH '94), solved by multigrid in a compiled core.
"""

from inkwarp._inkwarp import __version__
from inkwarp.drawing import sample
from inkwarp.errors import InkwarpError, SceneError
from inkwarp.imaging import warp_image

__all__ = ["InkwarpError", "SceneError", "__version__", "sample", "warp_image"]
