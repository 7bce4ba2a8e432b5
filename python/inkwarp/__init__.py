"""inkwarp: animate a still image by animating a drawing traced over it.

The grid thin plate of Litwinowicz & Williams ("Animating Images with Drawings",
SIGGRAPH '94), solved by multigrid in a compiled core.
"""

import os as _os
import signal as _signal
import sys as _sys


def _interrupted_while_starting(signum, frame):
    """Ctrl+C during the command line's imports (a few tenths of a second, before its own
    handling begins): the command's exit status and one line, not a traceback. Nothing is
    written yet, so nothing is left behind."""
    _sys.stderr.write("inkwarp: interrupted\n")
    _os._exit(130)


# Only in the `inkwarp` command (its console script), and only where Ctrl+C still raises
# KeyboardInterrupt; `inkwarp.cli.main` puts Python's handler back as it starts.
if (_os.path.basename(_sys.argv[0] if _sys.argv else "").removesuffix(".exe") == "inkwarp"
        and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler):
    _signal.signal(_signal.SIGINT, _interrupted_while_starting)

from inkwarp._inkwarp import __version__, _after_fork
from inkwarp.drawing import sample
from inkwarp.errors import ConvergenceWarning, InkwarpError, InkwarpWarning, InputError, PastEndWarning, SceneError
from inkwarp.compare import Comparison, compare, comparison_sheet
from inkwarp.methods import METHODS, ThinPlateMap, interpolate, interpolate_report
from inkwarp.imaging import warp_image
from inkwarp.transfer import transfer, transfer_dict
from inkwarp.track import track, track_dict
from inkwarp.plate import SolveReport, Solver, WarmStart, thin_plate, thin_plate_report
from inkwarp.scene import Frames, Scene, image_data_uri, scene_schema, validate_scene
from inkwarp.rendering import render

# A forked child builds its own engine threads (a fork copies none of the parent's).
_os.register_at_fork(after_in_child=_after_fork)

__all__ = [
    "Comparison",
    "ConvergenceWarning",
    "Frames",
    "InkwarpError",
    "InkwarpWarning",
    "InputError",
    "PastEndWarning",
    "METHODS",
    "Scene",
    "SceneError",
    "SolveReport",
    "ThinPlateMap",
    "__version__",
    "compare",
    "comparison_sheet",
    "image_data_uri",
    "interpolate",
    "interpolate_report",
    "render",
    "sample",
    "scene_schema",
    "thin_plate",
    "Solver",
    "WarmStart",
    "thin_plate_report",
    "track",
    "track_dict",
    "transfer",
    "transfer_dict",
    "validate_scene",
    "warp_image",
]
