"""Drawings: features sampled into (rest position, displacement) constraints."""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt

from inkwarp import _inkwarp
from inkwarp.errors import ArrayValuesError, InputError, real_array
from inkwarp.plate import _finite

#: The feature kinds, in the order the documentation lists them.
KINDS: tuple[str, ...] = ("point", "polyline", "spline", "region", "cut")

#: The outline curves a region may have.
CURVES: tuple[str, ...] = ("polyline", "spline")

Kind = Literal["point", "polyline", "spline", "region", "cut"]


def off_picture(points: np.ndarray, w: int, h: int, margin: float) -> np.ndarray:
    """Which of the ``(N, 2)`` points lie more than ``margin`` pixels off a ``w × h``
    picture (pixel centres 0 to w − 1, 0 to h − 1; a negative margin reaches inside it)."""
    return ((points < -margin) | (points > np.array([w - 1, h - 1]) + margin)).any(axis=1)


def _count(n: int) -> str:
    return f"{n} point" if n == 1 else f"{n} points"


def _points(name: str, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    try:
        arr = real_array(name, value, np.float64)
    except ArrayValuesError:
        raise
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"{name} must be an (N, 2) array of (x, y) numbers; it could not be read as numbers ({exc})."
        ) from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        hint = " For a single point, write [[x, y]]." if arr.shape == (2,) else ""
        raise InputError(
            f"{name} must be an (N, 2) array of (x, y) control points; got shape {arr.shape}.{hint}"
        )
    if arr.shape[0] == 0:
        raise InputError(f"{name} is empty; give the feature's control points as an (N, 2) array.")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{name}[{i}] is ({arr[i, 0]}, {arr[i, 1]}); every coordinate must be a finite number. "
            "Fix or remove that point."
        )
    return np.ascontiguousarray(arr)


def sample(
    kind: Kind | str,
    rest: npt.ArrayLike,
    pose: npt.ArrayLike,
    *,
    closed: bool = False,
    spacing: float = 1.0,
    shape: tuple[int, int] | None = None,
    curve: Literal["polyline", "spline"] | str = "polyline",
    mask: npt.ArrayLike | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Sample a feature into constraints for :func:`inkwarp.thin_plate`.

    Walks the feature's rest geometry at arc-length spacing no larger than `spacing`,
    vertices and end points included, and pairs every sample with the point of the posed
    geometry at the same primitive parameter (the same segment or span, the same parameter
    within it; for a segment, the same fraction of its length). A region also samples
    every grid node strictly inside its rest outline, moved by the mean-value-coordinate
    interpolation of the outline's displacements, so that an affine motion of a polyline
    outline moves the whole region by that map. See ``docs/concepts/drawings.md``.

    Parameters
    ----------
    kind : {"point", "polyline", "spline", "region", "cut"}
        The feature kind. ``"point"`` has exactly one position; ``"polyline"`` and
        ``"spline"`` (an interpolating centripetal Catmull-Rom curve) at least two
        control points; ``"region"`` at least three; a ``"cut"`` gives no samples.
    rest : array_like, shape (N, 2)
        The control points as traced over the original image, ``(x, y)`` in pixels
        (pixel centres at integers, y down).
    pose : array_like, shape (N, 2)
        The same control points in the pose (the same count as `rest`).
    closed : bool, default False
        Join a polyline's or spline's last point back to its first. Regions are always
        closed.
    spacing : float, default 1.0
        The largest arc length between consecutive samples, in pixels (the grid
        spacing).
    shape : tuple of int (H, W), optional
        The image's shape; required for a region, whose interior nodes are the grid's.
    curve : {"polyline", "spline"}, default "polyline"
        A region's outline: the closed polyline through its control points or the closed
        spline. Only regions take ``"spline"``.
    mask : array_like, shape (H, W), optional
        The continuity matte (nonzero = connected): a region samples only the interior
        nodes where it is nonzero. Needs `shape`.

    Returns
    -------
    points : ndarray of float64, shape (M, 2)
        The samples' rest positions: the curve samples in order along the curve, then a
        region's interior nodes row by row.
    displacements : ndarray of float64, shape (M, 2)
        How far each sample's partner in the pose has moved, ``(Δx, Δy)``.

    Raises
    ------
    ValueError
        An unknown kind or curve, arrays of the wrong shape, non-finite coordinates,
        different numbers of rest and pose points, too few points for the kind, a
        spacing that is not a positive number, or a region without `shape`.

    Examples
    --------
    A segment from (0, 0) to (4, 0) whose far end moves down by 2 px, sampled every
    pixel: each sample's partner is at the same fraction of the posed segment.

    >>> import inkwarp
    >>> points, moves = inkwarp.sample("polyline", [[0, 0], [4, 0]], [[0, 0], [4, 2]])
    >>> points.tolist()
    [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0]]
    >>> moves[:, 1].tolist()
    [0.0, 0.5, 1.0, 1.5, 2.0]

    A square region moved 3 px to the right: its outline samples and the nodes inside
    all move by (3, 0).

    >>> square = [[2, 2], [6, 2], [6, 6], [2, 6]]
    >>> moved = [[5, 2], [9, 2], [9, 6], [5, 6]]
    >>> points, moves = inkwarp.sample("region", square, moved, shape=(8, 8))
    >>> len(points), bool((abs(moves - [3, 0]) < 1e-9).all())
    (25, True)
    """
    if not isinstance(kind, str) or kind not in KINDS:
        raise InputError(f"unknown feature kind {kind!r}; the kinds are {', '.join(KINDS)}.")
    if not isinstance(curve, str) or curve not in CURVES:
        raise InputError(f"unknown curve {curve!r}; a region's outline is 'polyline' or 'spline'.")
    if curve == "spline" and kind != "region":
        raise InputError(
            f"curve='spline' is for region outlines only; for a spline feature use kind='spline' "
            f"(this feature is a {kind})."
        )
    rest_arr = _points("rest", rest)
    pose_arr = _points("pose", pose)
    if rest_arr.shape[0] != pose_arr.shape[0]:
        raise InputError(
            f"pose has {_count(pose_arr.shape[0])} but rest has {_count(rest_arr.shape[0])}; a pose "
            "moves the same control points as the rest, so give both the same number of rows."
        )
    if not (_finite(spacing) and spacing > 0):
        raise InputError(f"spacing must be a positive, finite number of pixels; got {spacing!r}.")
    spacing_px = float(spacing)
    if not (isinstance(closed, (bool, np.bool_)) or (isinstance(closed, (int, np.integer)) and closed in (0, 1))):
        raise InputError(f"closed must be True or False; got {closed!r}.")
    from inkwarp.methods import _shape
    from inkwarp.plate import _mask_u8

    grid_shape = None if shape is None else _shape(shape)
    if kind == "region" and grid_shape is None:
        raise InputError(
            "a region needs shape=(H, W), the image's height and width, to find the grid nodes "
            "inside its outline."
        )
    mask_arr = None
    if mask is not None:
        if grid_shape is None:
            raise InputError("mask needs shape: pass shape=(H, W) with the mask.")
        mask_arr = _mask_u8(mask, *grid_shape)
    return _inkwarp.sample_feature(
        kind,
        rest_arr,
        pose_arr,
        closed=bool(closed),
        spacing=spacing_px,
        spline_outline=(curve == "spline"),
        shape=grid_shape,
        mask=mask_arr,
    )
