"""inkwarp: animate a still image by animating a drawing traced over it.

The grid thin plate of Litwinowicz & Williams ("Animating Images with Drawings",
SIGGRAPH '94), solved by multigrid in a compiled core.
"""

from inkwarp._inkwarp import __version__
from inkwarp.drawing import sample
from inkwarp.errors import InkwarpError, SceneError
from inkwarp.compare import Comparison, compare, comparison_sheet
from inkwarp.methods import METHODS, ThinPlateMap, interpolate, interpolate_report
from inkwarp.imaging import warp_image
from inkwarp.transfer import transfer, transfer_dict
from inkwarp.plate import SolveReport, thin_plate, thin_plate_report

__all__ = [
    "Comparison",
    "InkwarpError",
    "METHODS",
    "SceneError",
    "SolveReport",
    "ThinPlateMap",
    "__version__",
    "compare",
    "comparison_sheet",
    "interpolate",
    "interpolate_report",
    "sample",
    "thin_plate",
    "thin_plate_report",
    "transfer",
    "transfer_dict",
    "warp_image",
]
