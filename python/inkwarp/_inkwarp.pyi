"""Type stubs for the compiled core. The public API is the `inkwarp` package."""

__version__: str
#: The limits every input is held to (see docs/reference/limits.md).
MAX_SIDE_PX: int
MAX_PIXELS: int
MAX_COORD_PX: float
MAX_TIME_S: float
MIN_FPS: float
MAX_FPS: float

def check_size(what: str, width: int, height: int) -> None: ...

# --- geometry (feature sampling) ---
import numpy as np
import numpy.typing as npt

def sample_feature(
    kind: str,
    rest: npt.NDArray[np.float64],
    pose: npt.NDArray[np.float64],
    closed: bool = False,
    spacing: float = 1.0,
    spline_outline: bool = False,
    shape: tuple[int, int] | None = None,
    mask: npt.NDArray[np.uint8] | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def curve_polyline(
    kind: str,
    points: npt.NDArray[np.float64],
    closed: bool = False,
    spline_outline: bool = False,
    spacing: float = 1.0,
) -> npt.NDArray[np.float64]: ...

# ---- scene ------------------------------------------------------------------------------

class SceneCore:
    """A resolved scene (images decoded, mattes and cuts applied); see `inkwarp.Scene`."""

    @staticmethod
    def from_json(text: str, base_dir: str | None = None, file: str | None = None) -> SceneCore: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def fps(self) -> float: ...
    @property
    def duration(self) -> float: ...
    @property
    def frame_count(self) -> int: ...
    @property
    def render_bytes(self) -> int: ...
    @property
    def layer_names(self) -> list[str]: ...
    @property
    def feature_ids(self) -> list[str]: ...
    def frame_time(self, frame: int) -> float: ...
    def warm_starts(self, method: str | None = None) -> bool: ...
    def doc_json(self) -> str: ...
    def render(self, time: float, method: str | None = None) -> npt.NDArray[np.uint8]: ...
    def field(self, layer: int, time: float, method: str | None = None) -> npt.NDArray[np.float32]: ...
    def frames(self, start: int, stop: int, threads: int = 0, method: str | None = None) -> FrameIter: ...
    def render_detailed(
        self, time: float, layer: int, overrides: str | None = None
    ) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32], list[str]]:
        """The frame with solver `overrides` (JSON) over every layer's own, layer `layer`'s
        field, and every layer's interpolant notes."""

class FrameIter:
    """Frames `(index, RGBA uint8 (H, W, 4))` in order, rendered on worker threads."""

    def __iter__(self) -> FrameIter: ...
    def __next__(self) -> tuple[int, npt.NDArray[np.uint8]]: ...
    def __len__(self) -> int: ...
    def close(self) -> None: ...

def scene_schema() -> str: ...
def scene_problems(text: str, base_dir: str | None = None) -> list[tuple[str, str]]: ...
def video_kind(data: bytes) -> str | None:
    """The kind of video the bytes start as ("MP4", "MOV", "WebM", "Matroska", "AVI"), or None
    (a HEIC or AVIF picture is not one)."""

# --- render (forward mapping) ---
def warp_image(
    image: npt.NDArray[np.uint8],
    field: npt.NDArray[np.float32],
    matte: npt.NDArray[np.uint8],
    cuts: list[npt.NDArray[np.float64]],
) -> npt.NDArray[np.uint8]:
    """Forward-map C-contiguous uint8 RGBA (H, W, 4) by float32 (H, W, 2) over uint8 matte
    (H, W), its links crossed by the (K, 2) float64 cuts removed; see `inkwarp.warp_image` for the checked, documented entry point."""

def decode_picture(data: bytes) -> npt.NDArray[np.uint8]:
    """A PNG or JPEG file's bytes as the engine decodes a scene's pictures: straight RGBA
    (H, W, 4), upright by the EXIF orientation it reads; ValueError says why not."""

# --- methods (comparison interpolants, thin-plate map, transfer) ---
from typing import Any

def interpolate_field(
    method: str,
    points: npt.NDArray[np.float64],
    displacements: npt.NDArray[np.float64],
    height: int,
    width: int,
    lines_rest: npt.NDArray[np.float64] | None = None,
    lines_pose: npt.NDArray[np.float64] | None = None,
    max_samples: int = 1000,
    a: float = 1.0,
    b: float = 2.0,
    p: float = 0.0,
) -> tuple[npt.NDArray[np.float32], dict[str, Any]]: ...

# --- thin plate (inkwarp.plate) -------------------------------------------------------
class WarmStart:
    """Earlier solves of one animated surface; see `inkwarp.WarmStart`."""

    def __init__(self) -> None: ...
    def clear(self) -> None: ...
    def __len__(self) -> int: ...

class Solver:
    """A solver kept between calls; see `inkwarp.Solver`."""

    def __init__(self) -> None: ...
    def clear(self) -> None: ...

def thin_plate_solve(
    points: npt.NDArray[np.float64],
    displacements: npt.NDArray[np.float64],
    height: int,
    width: int,
    mask: npt.NDArray[np.uint8] | None,
    cuts: list[npt.NDArray[np.float64]],
    tension: float,
    tolerance: float,
    grid_step: int,
    initial: npt.NDArray[np.float32] | None,
    max_cycles: int | None,
    method: str,
    southwell_sweeps: float,
    warm: WarmStart | None = None,
    off: str = "",
    solver: Solver | None = None,
) -> tuple[npt.NDArray[np.float32], dict[str, Any]]: ...

class ThinPlateMap:
    def __init__(self, source: npt.ArrayLike, target: npt.ArrayLike) -> None: ...
    def __call__(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
    def field(self, height: int, width: int) -> npt.NDArray[np.float32]: ...
    def __len__(self) -> int: ...

def posed_drawing(
    doc_json: str, time: float, spacing: float = 1.0
) -> list[tuple[str, str, npt.NDArray[np.float64]]]: ...
def transfer_keys(
    source: list[tuple[str, str, list[tuple[float, float]], list[list[tuple[float, float]]]]],
    target: list[tuple[str, str, list[tuple[float, float]], list[list[tuple[float, float]]]]],
) -> list[list[list[tuple[float, float]]] | None]: ...
def transfer_fold(
    source: list[tuple[str, str, list[tuple[float, float]], list[list[tuple[float, float]]]]],
    target: list[tuple[str, str, list[tuple[float, float]], list[list[tuple[float, float]]]]],
) -> tuple[float, float, str, str] | None: ...
def _panic_for_tests() -> None: ...
def _after_fork() -> None: ...
