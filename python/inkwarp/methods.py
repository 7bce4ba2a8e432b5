"""The other interpolants the paper compares the grid thin plate against.

Every method turns the same drawing samples into a displacement field of the same
layout as :func:`inkwarp.thin_plate` (float32 ``(H, W, 2)``, ``[..., 0] = Δx``), so that
the same renderer can draw them and a comparison is only about the surface:

=================  =============================================================  ==========
method             what it is                                                     holes/cuts
=================  =============================================================  ==========
``tps``            the grid thin plate (:func:`inkwarp.thin_plate`)               yes
``tps-exact``      the continuous thin-plate spline (``r² log r`` + affine),      no
                   fitted to the samples and evaluated at every pixel
``triangulation``  Delaunay triangulation of the samples and the four image       no
                   corners (held at zero), linear in each triangle
``beier-neely``    Beier & Neely's line-pair field for segments, Shepard          no
                   weights for points
=================  =============================================================  ==========

See ``docs/concepts/comparison.md`` for pictures of each.
"""

from __future__ import annotations

import math

from typing import Any, Sequence

import numpy as np

from inkwarp import _inkwarp
from inkwarp.errors import ArrayValuesError, InputError, real_array

__all__ = ["METHODS", "ThinPlateMap", "interpolate", "interpolate_report"]

#: Every method name, in the order comparisons show them.
METHODS: tuple[str, ...] = ("tps", "tps-exact", "triangulation", "beier-neely")

class ThinPlateMap:
    """The continuous thin-plate map taking ``source`` points onto ``target`` points.

    ``W(p) = p + f(p)`` with each component of ``f`` an ``r² log r`` spline plus an
    affine part, exact at every source point and of least bending energy; affine maps
    are reproduced exactly. Animation transfer (:func:`inkwarp.transfer`) maps the
    source's keys through it. A source point given twice is merged (targets averaged).

    Parameters
    ----------
    source, target : array_like, shape (N, 2)
        Corresponding points.

    Examples
    --------
    >>> import inkwarp
    >>> w = inkwarp.ThinPlateMap([[0, 0], [10, 0], [0, 10]], [[0, 0], [20, 0], [0, 20]])
    >>> w([[5, 5]]).round(9).tolist()
    [[10.0, 10.0]]
    >>> w.field(3, 4).shape
    (3, 4, 2)
    >>> import pickle
    >>> pickle.loads(pickle.dumps(w))([[5, 5]]).round(9).tolist()
    [[10.0, 10.0]]
    """

    def __init__(self, source: Any, target: Any) -> None:
        self._points = (_points("source", source), _points("target", target))
        self._map = _inkwarp.ThinPlateMap(*self._points)

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled (to a process pool, say) and copied as its points, fitted again."""
        return (ThinPlateMap, self._points)

    def __call__(self, points: Any) -> np.ndarray:
        """Map ``(N, 2)`` points; returns float64 ``(N, 2)``."""
        return self._map(_points("points", points))

    def field(self, height: int, width: int) -> np.ndarray:
        """The displacement ``W(p) − p`` at every pixel, float32 ``(H, W, 2)``."""
        h, w = _shape((height, width))
        return self._map.field(h, w)

    def __len__(self) -> int:
        return len(self._map)

    def __repr__(self) -> str:
        return f"ThinPlateMap({len(self)} centres)"


def check_method(method: str) -> str:
    """Return ``method`` if it is a known method name, else raise ``ValueError``."""
    if method not in METHODS:
        known = ", ".join(f'"{m}"' for m in METHODS)
        raise InputError(f'unknown method "{method}": use one of {known}.')
    return method


def _points(name: str, value: Any) -> np.ndarray:
    arr = real_array(name, value, np.float64)
    if arr.size == 0:
        arr = arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InputError(f"{name} must be an (N, 2) array of (x, y) pairs; got shape {arr.shape}.")
    if not np.isfinite(arr).all():
        row = int(np.argwhere(~np.isfinite(arr))[0][0])
        raise InputError(f"{name}[{row}] is not finite ({arr[row].tolist()}); remove it or fix it.")
    return np.ascontiguousarray(arr)


def _segments(name: str, value: Any) -> np.ndarray:
    try:
        arr = real_array(name, value, np.float64)
    except ArrayValuesError:
        raise
    except (TypeError, ValueError):  # text, None, ragged nesting: numpy's words would not name it
        raise InputError(f"{name} must be an (L, 2, 2) array of numbers: L segments of two (x, y) end points; "
                         f"got {value!r:.40}") from None
    if arr.size == 0:
        arr = arr.reshape(0, 2, 2)
    if arr.ndim != 3 or arr.shape[1:] != (2, 2):
        raise InputError(
            f"{name} must be an (L, 2, 2) array: L segments of two (x, y) end points; got shape {arr.shape}."
        )
    if not np.isfinite(arr).all():
        raise InputError(f"{name} holds a value that is not finite; every end point must be a finite number.")
    return np.ascontiguousarray(arr)


def _shape(shape: Sequence[int]) -> tuple[int, int]:
    from inkwarp.plate import _size

    try:
        height, width = (_size(v) for v in shape)  # whole numbers: 16.7 is refused, not cut
    except (TypeError, ValueError):
        raise InputError(f"shape must be (H, W); got {shape!r}.") from None
    if height < 1 or width < 1:
        raise InputError(f"shape must be at least (1, 1); got ({height}, {width}).")
    if max(height, width) > _inkwarp.MAX_SIDE_PX:
        raise InputError(f"shape ({height}, {width}): each side may be at most "
                         f"{_inkwarp.MAX_SIDE_PX} pixels; use a smaller grid.")
    return height, width


def interpolate_report(
    points: Any,
    displacements: Any,
    shape: Sequence[int],
    *,
    method: str = "tps-exact",
    lines: tuple[Any, Any] | None = None,
    max_samples: int = 1000,
    a: float = 1.0,
    b: float = 2.0,
    p: float = 0.0,
) -> tuple[np.ndarray, dict[str, Any]]:
    """:func:`interpolate`, also returning what the method did.

    Returns
    -------
    field : numpy.ndarray
        float32 ``(H, W, 2)``.
    report : dict
        ``method``, ``samples_given``, ``samples_used`` (distinct positions fitted),
        ``line_pairs_used``, ``dropped``, ``ignored_matte``, ``notes`` (sentences worth
        showing, such as a thinning) and ``seconds``.

    Examples
    --------
    >>> import inkwarp
    >>> pts = [[float(x), float(y)] for x in range(0, 50, 2) for y in (10.0, 11.0)]
    >>> field, report = inkwarp.interpolate_report(pts, [[1.0, 0.0]] * len(pts), (32, 48),
    ...                                            max_samples=20)
    >>> report["samples_used"], report["notes"][0][:40]
    (20, 'tps-exact thinned 50 distinct sample pos')
    """
    check_method(method)
    if isinstance(max_samples, (bool, np.bool_)) or not isinstance(max_samples, (int, np.integer)) \
            or not 1 <= max_samples <= 2**32 - 1:
        raise InputError(f"max_samples must be a whole number from 1 to {2**32 - 1}; got {max_samples!r}.")
    pts = _points("points", points)
    disp = _points("displacements", displacements)
    if len(pts) != len(disp):
        raise InputError(
            f"points and displacements must have the same length; got {len(pts)} points "
            f"and {len(disp)} displacements."
        )
    height, width = _shape(shape)
    rest = pose = None
    if lines is not None:
        try:
            if isinstance(lines, (str, bytes)):
                raise TypeError
            rest_in, pose_in = lines
        except (TypeError, ValueError):
            raise InputError("lines must be a pair (rest, pose) of (L, 2, 2) segment arrays.") from None
        rest, pose = _segments("lines[0] (rest)", rest_in), _segments("lines[1] (pose)", pose_in)
        if rest.shape != pose.shape:
            raise InputError(
                f"lines: the rest and pose segments must match; got {len(rest)} and {len(pose)} segments."
            )
    if method == "tps":
        from inkwarp import thin_plate_report

        if rest is not None and pose is not None and len(rest):
            ends = rest.reshape(-1, 2)
            pts = np.concatenate([pts, ends])
            disp = np.concatenate([disp, pose.reshape(-1, 2) - ends])
        if len(pts) == 0:
            return np.zeros((height, width, 2), np.float32), _tps_report(0, 0, 0.0)
        field, solved = thin_plate_report(pts, disp, (height, width))
        report = _tps_report(len(pts), solved.constrained_samples, solved.seconds)
        report["dropped"] = solved.dropped_samples
        if not solved.converged:
            report["notes"].append(f"the thin-plate solve did not converge (stopped: {solved.stop}, after "
                                   f"{solved.cycles} cycles)")
        return field, report
    # Beier–Neely's weights (the other methods take none).
    weights = [_weight("a", a, 1e6, above_zero=True), _weight("b", b, 16.0), _weight("p", p, 16.0)] \
        if method == "beier-neely" else [1.0, 2.0, 0.0]
    field, report = _inkwarp.interpolate_field(method, pts, disp, height, width, rest, pose, int(max_samples), *weights)
    return field, report


def _weight(name: str, value: Any, most: float, above_zero: bool = False) -> float:
    """A Beier–Neely weight as a float: a real number from 0 (above it where ``above_zero``)
    to ``most``, or a ValueError naming it and its range."""
    span = f"above 0 and at most {most:.0e}".replace("e+0", "e") if above_zero else f"from 0 to {most:g}"
    from inkwarp.plate import _finite

    number = float(value) if _finite(value) else math.nan
    if not ((number > 0 if above_zero else number >= 0) and number <= most):
        raise InputError(f"{name} must be a number {span}; got {value!r}.")
    return number


def _tps_report(given: int, used: int, seconds: float) -> dict[str, Any]:
    return {
        "method": "tps",
        "samples_given": given,
        "samples_used": used,
        "line_pairs_used": 0,
        "dropped": 0,
        "ignored_matte": False,
        "notes": [],
        "seconds": seconds,
    }


def interpolate(
    points: Any,
    displacements: Any,
    shape: Sequence[int],
    *,
    method: str = "tps-exact",
    lines: tuple[Any, Any] | None = None,
    max_samples: int = 1000,
    a: float = 1.0,
    b: float = 2.0,
    p: float = 0.0,
) -> np.ndarray:
    """The displacement field of the samples by one of the comparison methods.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Rest positions ``(x, y)`` in pixels (pixel centres at integers, y down).
    displacements : array_like, shape (N, 2)
        How far each point moves, ``(Δx, Δy)``.
    shape : (H, W)
        Size of the field.
    method : {"tps-exact", "triangulation", "beier-neely", "tps"}
        ``"tps-exact"``: the continuous thin-plate spline, exact at every sample; more
        than ``max_samples`` distinct positions are thinned by farthest-point sampling
        (deterministic; isolated samples are always kept). ``"triangulation"``:
        Delaunay triangulation of the points plus the four corner pixels held at zero,
        linear inside each triangle. ``"beier-neely"``: the points weighted by Shepard's
        ``1 / (a + d)^b`` and the ``lines`` by Beier & Neely's
        ``(length^p / (a + d))^b``. ``"tps"``: :func:`inkwarp.thin_plate` on the points
        (and the lines' end points).
    lines : (rest, pose), optional
        Segments for Beier–Neely: two ``(L, 2, 2)`` arrays of end points before and
        after. The other methods interpolate their end points as extra samples.
    max_samples : int
        ``tps-exact`` fits at most this many samples (default 1000).
    a, b, p : float
        Beier–Neely weights (defaults 1 px, 2, 0): ``a`` > 0 how tightly a primitive
        holds what lies on it, ``b`` ≥ 0 how fast influence falls off, ``p`` ≥ 0 how
        much longer lines outweigh short ones.

    Returns
    -------
    numpy.ndarray
        float32 ``(H, W, 2)``: ``[..., 0]`` is Δx, ``[..., 1]`` is Δy.

    Raises
    ------
    ValueError
        Unknown method, wrong shapes, non-finite values, bad parameters.

    Notes
    -----
    None of these methods has a notion of a continuity matte or a cut: their surfaces
    are continuous across holes, which is what the paper's comparison shows.

    Examples
    --------
    One point pulled right, the corners held, by triangulation:

    >>> import inkwarp
    >>> f = inkwarp.interpolate([[4, 4]], [[3.0, 0.0]], (9, 9), method="triangulation")
    >>> f.shape, f.dtype, f[4, 4].tolist(), f[0, 0].tolist(), float(f[2, 2, 0])
    ((9, 9, 2), dtype('float32'), [3.0, 0.0], [0.0, 0.0], 1.5)

    A line pair moved rigidly moves everything rigidly under Beier–Neely:

    >>> import numpy as np
    >>> rest = np.array([[[2.0, 2.0], [6.0, 2.0]]])
    >>> f = inkwarp.interpolate(np.zeros((0, 2)), np.zeros((0, 2)), (8, 8),
    ...                         method="beier-neely", lines=(rest, rest + [1.0, 2.0]))
    >>> np.allclose(f, [1.0, 2.0])
    True
    """
    return interpolate_report(
        points,
        displacements,
        shape,
        method=method,
        lines=lines,
        max_samples=max_samples,
        a=a,
        b=b,
        p=p,
    )[0]
