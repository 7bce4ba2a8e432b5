"""Type stubs for the compiled core. The public API is the `inkwarp` package."""

__version__: str

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

# --- render (forward mapping) ---
def warp_image(
    image: npt.NDArray[np.uint8], field: npt.NDArray[np.float32], matte: npt.NDArray[np.uint8]
) -> npt.NDArray[np.uint8]:
    """Forward-map C-contiguous uint8 RGBA (H, W, 4) by float32 (H, W, 2) over uint8 matte
    (H, W); see `inkwarp.warp_image` for the checked, documented entry point."""

# --- thin plate (inkwarp.plate) -------------------------------------------------------
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
) -> tuple[npt.NDArray[np.float32], dict[str, int | float | bool]]:
    """Solve the grid thin plate; the field (H, W, 2) and the report as a dict."""
