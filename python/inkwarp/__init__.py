"""inkwarp: animate a still image by animating a drawing traced over it.

The grid thin plate of Litwinowicz & Williams ("Animating Images with Drawings",
SIGGRAPH '94), solved by multigrid in a compiled core.
"""

from inkwarp._inkwarp import __version__
from inkwarp.drawing import sample
from inkwarp.errors import InkwarpError, SceneError
from inkwarp.imaging import warp_image
from inkwarp.plate import SolveReport, thin_plate, thin_plate_report
from inkwarp.scene import Frames, Scene, image_data_uri, scene_schema, validate_scene

__all__ = [
    "Frames",
    "InkwarpError",
    "Scene",
    "SceneError",
    "SolveReport",
    "__version__",
    "image_data_uri",
    "sample",
    "scene_schema",
    "thin_plate",
    "thin_plate_report",
    "validate_scene",
    "warp_image",
]
