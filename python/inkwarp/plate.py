"""The grid thin plate: a smooth displacement field from scattered displacements.

``thin_plate`` interpolates displacements given at points over a whole image grid by
minimising the discrete thin-plate energy (plus an optional membrane term) of
``docs/concepts/thin-plate.md``, with holes (a continuity mask) and cuts as real
discontinuities. The work happens in the compiled core; the GIL is released during the
solve.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import operator
import os
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from inkwarp import _inkwarp
from inkwarp.errors import ArrayValuesError, ConvergenceWarning, InkwarpWarning, InputError, real_array

__all__ = ["SolveReport", "Solver", "WarmStart", "thin_plate", "thin_plate_report"]

_METHODS = ("multigrid", "southwell")

#: The largest ``max_cycles`` taken, as in scenes (the engine counts cycles in 32 bits).
MAX_CYCLES = 2**32 - 1

WarmStart = _inkwarp.WarmStart
WarmStart.__doc__ = """Earlier solves of one animated surface, to start the next solve from.

Pass the same ``WarmStart`` as ``warm=`` to every frame's :func:`thin_plate` call, with
the same grid and the same points (only their displacements changing). The solution is
linear in the displacements, so each solve starts from the combination of the last three
frames' fields that best matches the new displacements (least squares); along a smooth
motion that is an extrapolation, far closer than the previous field alone. Frames with
other points or another grid (another size, mask or cuts) start the series over; their
first frame still starts from the previous field where that is closer than none. A frame
that did not converge is no start: the next one starts cold (from its error the stopping
rule could claim convergence it had not reached); a ``southwell`` frame, unconverged by
design, stays a start. (Its solver does not keep the pieces' answers as a ``Solver`` does:
the frames before predict the next as closely, sooner.) ``clear()`` starts over by hand.

What it keeps is a cache: a ``WarmStart`` pickled (to a process pool, say) or copied is a
fresh, empty one, whose first solve starts cold.

Examples
--------
>>> import numpy as np, inkwarp
>>> warm = inkwarp.WarmStart()
>>> pts = [[8, 8], [56, 8], [8, 40], [56, 40], [32, 24]]
>>> cycles = []
>>> for t in np.linspace(0, 1, 8):
...     disp = [[0, 0]] * 4 + [[6 * np.sin(3 * t), 4 * np.cos(3 * t)]]
...     field, report = inkwarp.thin_plate_report(pts, disp, (48, 64), warm=warm)
...     cycles.append(report.cycles)
>>> len(warm), cycles[-1] <= cycles[0]
(3, True)
"""

Solver = _inkwarp.Solver
Solver.__doc__ = """A thin-plate solver kept between calls, for many solves on one grid.

Pass the same ``Solver`` as ``solver=`` to :func:`thin_plate` calls on the same grid (and
mask and cuts) with the same points: the coarse levels it built for the first call, and on
a grid with holes or cuts the free functions it found (hinges, strands), are reused for
every piece of the grid, which takes the later calls' setup away; as many of the points
before stay too, for an undo (within about 4 million nodes). What the latest call used is
kept whatever the grid's size, about 150 bytes a node of the grid it solves on (and about
1,300 more a node of its thin parts: strands, teeth and outlines, factored exactly), until
the ``Solver`` is dropped. The slow modes a long solve finds (parts turning on thin necks)
are not kept for the next call (corrected on against another call's residual they moved
hair strands by hundreds of pixels); a call on a grid where they were found keeps its own
search directions from its first cycle instead, to find them again before it stops.

A ``Solver`` also keeps each piece's converged answers from its second call on (one field
per point of the piece at most, and none past 64 MB a piece). The answer is linear in the
displacements, so once the kept answers' displacements span the new ones (with 10 points:
five calls with independent displacements after the first; one for a repeat or a uniform
scaling), a call starts from the same combination of their answers, in place of
``initial`` (unless that already meets the tolerance), where the error the combination
carries (the earlier solves' own estimates) is within the accuracy a converged solve
promises; it then takes a cycle (two where holes or cuts tear the piece: the stopping
rule needs a ratio of changes). A start refused for
that error still teaches the solver: its answer replaces the field the error came from.
Not on pieces with free functions (hinges, strands, a tension's tilt about one line of
points) or a gauge pin, nor with ``method="southwell"`` or ``max_cycles=0`` (the answer is
then the start).

So answers through a ``Solver`` agree with calls without it within the tolerance, and bit
for bit where no earlier call left answers that span the new displacements or probed the
piece (a later warm start then keeps its search directions from its first cycle).
``clear()`` forgets the answers (the next call starts from ``initial`` or from scratch) and
keeps the levels. Without a ``Solver`` every call builds its levels afresh and keeps
nothing. A ``WarmStart`` keeps a solver of its own, so the two are not passed together.

What it keeps is a cache: a ``Solver`` pickled (to a process pool, say) or copied is a
fresh, empty one, which builds its levels again on its first call.

Examples
--------
>>> import numpy as np, inkwarp
>>> solver = inkwarp.Solver()
>>> pts = [[8, 8], [56, 8], [8, 40], [56, 40], [32, 24]]
>>> for d in (1, 2):  # the first call's answer is not kept: a solver used once would pay for nothing
...     _ = inkwarp.thin_plate(pts, [[0, 0]] * 4 + [[d, 0]], (48, 64), solver=solver)
>>> kept, report = inkwarp.thin_plate_report(pts, [[0, 0]] * 4 + [[3, 0]], (48, 64), solver=solver)
>>> fresh = inkwarp.thin_plate(pts, [[0, 0]] * 4 + [[3, 0]], (48, 64))
>>> report.cycles, bool(np.abs(kept - fresh).max() < 0.01)
(1, True)
>>> solver.clear()
>>> again = inkwarp.thin_plate(pts, [[0, 0]] * 4 + [[3, 0]], (48, 64), solver=solver)
>>> bool(np.array_equal(again, fresh))
True
"""


def _fresh(cache: Any) -> tuple[Any, tuple[()]]:
    """Pickled or copied, a ``Solver`` or ``WarmStart`` is a new, empty one of its kind: it
    holds an engine cache, which neither pickles nor needs to (the answers do not depend on it
    beyond the tolerance), and its constructor takes no settings."""
    return type(cache), ()


Solver.__reduce__ = _fresh
WarmStart.__reduce__ = _fresh


@dataclasses.dataclass(frozen=True)
class SolveReport:
    """What one thin-plate solve did.

    Attributes
    ----------
    cycles : int
        Multigrid cycles run after the coarse-to-fine start (``"southwell"``: rounds of one
        coarse correction and one sweep's worth of relaxations). Pieces of the grid that holes or cuts separate are solved apart; this is
        the most cycles any of them took, and the change and residuals below are the
        largest over them.
    final_change : float
        Largest change of any node during the last cycle, in pixels.
    residual : float
        Largest residual of any free node after the solve, divided by its diagonal
        (pixels: how far one more relaxation of that node would move it).
    initial_residual : float
        The same before the first cycle.
    constrained_nodes : int
        Grid nodes fixed by the points (several points on one node count once; with
        ``grid_step`` > 1, nodes of the coarse grid solved).
    constrained_samples : int
        Points that constrain a node. With ``grid_step`` > 1, the points on each
        constrained coarse node, of which the nearest to it sets its value.
    dropped_samples : int
        Points that fell outside the grid or on a masked-out node. With ``grid_step`` > 1,
        also points whose nearest coarse node is masked out; a part of the matte with no
        coarse node at all (a strip thinner than the step) still moves by the mean of
        its points, dropped or not.
    seconds : float
        Wall time of the solve.
    converged : bool
        Whether the tolerance was met within ``max_cycles`` (``"southwell"``: the same error
        bound; a spent budget is not convergence).
    stop : str
        Why the solve stopped: ``"converged"`` (exactly when ``converged``),
        ``"max_cycles"`` (the cycles ran out), ``"budget"`` (``"southwell"``'s fixed budget
        was spent), ``"unsettled"`` (parts joined at single nodes or by 1 px strands too
        many to settle to the tension → 0 rule, or not settling within its rounds),
        ``"precision"`` (a tolerance finer than the field's ``float32`` precision, reported
        even where the cycles ran out too), ``"residual"`` (the stopping rule's claim left a
        residual above the tolerance), ``"breakdown"`` (a value not finite) or
        ``"interrupted"``. With several pieces, the first reason found.
    probe_cycles : int
        Cycles a slow solve of a piece with holes or cuts spent probing its operator for
        slow modes (24 a probe, on a random start: in every solve still running at cycle 20,
        or before a weakly held piece's first claim where no earlier solve of the ``Solver``
        found its slow modes), beside ``cycles``: they are not counted there, nor against
        ``max_cycles``. With several pieces, the sum over them.
    """

    cycles: int
    final_change: float
    residual: float
    initial_residual: float
    constrained_nodes: int
    constrained_samples: int
    dropped_samples: int
    seconds: float
    converged: bool
    stop: str = "converged"
    probe_cycles: int = 0


def _size(value: Any) -> int:
    if isinstance(value, (bool, np.bool_)):
        raise TypeError("a bool is not a size")
    return operator.index(value)


def _finite(value: Any) -> bool:
    """Whether ``value`` is a real number (not a bool; a 0-d array holding one counts) that a
    float holds finitely."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int past 1.8e308
        return False


def _shown(value: Any) -> str:
    """``value`` for a message: an integer too long to read as its number of digits."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return repr(value)
    if not isinstance(value, numbers.Integral):
        text = f"{float(value):.15g}"  # numpy's scalars as plain numbers, a float as one (2.0)
        return text if any(c in text for c in ".eni") else f"{text}.0"
    bits = abs(int(value)).bit_length()
    if bits <= 80:
        return str(int(value))
    # Its digit count, without writing it out (Python refuses past 4300 digits).
    digits = len(str(abs(int(value)))) if bits < 14000 else f"about {int(bits * 0.30103)}"
    return f"{'a negative' if value < 0 else 'an'} integer of {digits} digits"


def _first_line(exc: BaseException) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _points(name: str, value: Any) -> npt.NDArray[np.float64]:
    try:
        arr = real_array(name, value, np.float64)
    except ArrayValuesError:
        raise
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an (N, 2) array of numbers ({exc}).") from None
    if arr.size == 0:
        arr = arr.reshape(0, 2)  # an empty list: "empty", below, not a shape to fix
    if arr.ndim == 0:  # None, or one number: no reshaping makes positions of it
        raise InputError(f"{name} must be an (N, 2) array with one (x, y) pair per row, got {value!r:.40}.")
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InputError(
            f"{name} must have shape (N, 2) with one (x, y) pair per row, got shape "
            f"{arr.shape}; reshape it, e.g. np.asarray({name}).reshape(-1, 2)."
        )
    if not np.all(np.isfinite(arr)):
        row = int(np.argwhere(~np.isfinite(arr))[0][0])
        raise InputError(f"{name} has a value that is not a finite number (NaN, None or infinite) in row {row}; "
                         "every value must be a finite number.")
    return np.ascontiguousarray(arr)


def _cuts(cuts: Any) -> list[np.ndarray]:
    """``cuts`` (None, or a list of (K, 2) polylines of at least two points) as a list of
    contiguous float64 arrays; ``ValueError`` naming the cut otherwise."""
    if cuts is None:
        return []
    try:
        polylines = not isinstance(cuts, (str, bytes)) and iter(cuts) is not None
    except TypeError:  # not iterable
        polylines = False
    if not polylines:
        raise InputError(f"cuts must be a list of (K, 2) polylines, got {cuts!r:.40}.")
    cuts = cuts if isinstance(cuts, np.ndarray) else list(cuts)  # a generator is read once
    try:  # its depth: 2 is one polyline without the list around it, 1 a list of numbers
        with warnings.catch_warnings():  # (numpy's ComplexWarning: complex values are said below, by name)
            warnings.simplefilter("ignore")
            depth = np.asarray(cuts, dtype=float).ndim if len(cuts) > 0 else None
    except (TypeError, ValueError, OverflowError):  # ragged polylines, or a value said below by name
        depth = None
    if depth == 2 and all(np.size(c) == 0 for c in cuts):
        depth = None  # (empty cuts, said below as such)
    if depth == 2:
        raise InputError("cuts must be a list of (K, 2) polylines; wrap a single cut in a list: cuts=[cut].")
    if depth == 1:  # numbers: [x0, y0, x1, y1]
        raise InputError(f"cuts must be a list of (K, 2) polylines, got a list of numbers {cuts!r:.40}; give each "
                         "cut's points as pairs, such as cuts=[[[x0, y0], [x1, y1]]].")
    cut_list = []
    for k, cut in enumerate(cuts):
        c = _points(f"cuts[{k}]", cut)
        if len(c) < 2:
            raise InputError(f"cuts[{k}] has {len(c)} point(s); a cut needs at least two (x, y) points.")
        cut_list.append(c)
    return cut_list


def _mask_u8(mask: Any, height: int, width: int, name: str = "mask") -> np.ndarray:
    """An ``(H, W)`` mask or matte as uint8 (1 where nonzero), or a ValueError naming
    ``name`` and the fix."""
    if isinstance(mask, (str, bytes, os.PathLike)):
        raise InputError(f"{name} must be an (H, W) array, got the path {os.fspath(mask)!r}; read the picture "
                         "first (its alpha, for example np.asarray(PIL.Image.open(path).convert('RGBA'))[..., 3]).")
    try:
        m = np.asarray(mask)
    except (TypeError, ValueError) as exc:  # rows of different lengths, for example
        raise InputError(f"{name} must be an (H, W) array of numbers ({_first_line(exc)}).") from None
    if m.ndim == 3 and m.shape[:2] == (height, width):
        one = f"a picture's alpha is {name}[..., 3]" if m.shape[2] == 4 else f"such as {name}[..., 0]"
        raise InputError(f"{name} has shape {m.shape}: a picture's channels; pass one of them, an (H, W) array ({one}).")
    if m.shape != (height, width):
        against = "the image is" if name == "matte" else "shape is"
        raise InputError(f"{name} has shape {m.shape} but {against} {(height, width)}; pass an (H, W) {name}.")
    if m.dtype.kind == "f" and not np.all(np.isfinite(m)):
        raise InputError(f"{name} has NaN or infinite values; use 0 for holes and nonzero for connected pixels.")
    if m.dtype.kind not in "biuf":
        raise InputError(f"{name} must hold numbers or booleans (nonzero = connected), got dtype {m.dtype}.")
    return np.ascontiguousarray(m != 0, dtype=np.uint8)


def _check_args(
    points: Any,
    displacements: Any,
    shape: Any,
    mask: Any,
    cuts: Any,
    tension: Any,
    tolerance: Any,
    grid_step: Any,
    initial: Any,
    max_cycles: Any,
    method: Any,
    southwell_sweeps: Any,
) -> dict[str, Any]:
    try:
        height, width = (_size(v) for v in shape)
    except (TypeError, ValueError):
        raise InputError(f"shape must be (height, width), two positive integers, got {shape!r}.") from None
    if height < 1 or width < 1:
        raise InputError(f"shape must be (height, width), two positive integers, got {shape!r}.")
    if max(height, width) > _inkwarp.MAX_SIDE_PX:
        raise InputError(f"shape {shape!r}: each side may be at most {_inkwarp.MAX_SIDE_PX} "
                         "pixels; use a smaller grid.")
    pts = _points("points", points)
    disp = _points("displacements", displacements)
    if len(pts) == 0:
        raise InputError("points is empty: pass at least one (x, y) point with its displacement.")
    if len(pts) != len(disp):
        raise InputError(
            f"points has {len(pts)} rows but displacements has {len(disp)}; pass one displacement per point."
        )
    mask_u8 = None if mask is None else _mask_u8(mask, height, width)
    cut_list = _cuts(cuts)
    for name, value in (("tension", tension), ("tolerance", tolerance)):
        if not _finite(value) or value < 0:
            raise InputError(f"{name} must be a finite number >= 0, got {_shown(value)}.")
    if tension > 1e6:
        raise InputError(f"tension must be a number from 0 to 1e6 (0 is a pure thin plate), got {_shown(tension)}.")
    if (isinstance(grid_step, bool) or not isinstance(grid_step, numbers.Integral) or grid_step < 1
            or grid_step > _inkwarp.MAX_SIDE_PX):
        raise InputError(f"grid_step must be an integer from 1 to {_inkwarp.MAX_SIDE_PX} (1 solves on every "
                         f"pixel), got {_shown(grid_step)}.")
    if max_cycles is not None and (
        isinstance(max_cycles, bool) or not isinstance(max_cycles, numbers.Integral)
        or not 0 <= max_cycles <= MAX_CYCLES
    ):
        raise InputError(f"max_cycles must be None (the default cap, 300) or an integer from 0 to {MAX_CYCLES:,}, "
                         f"got {_shown(max_cycles)}.")
    if method not in _METHODS:
        raise InputError(f"method must be one of {_METHODS}, got {method!r}.")
    if not _finite(southwell_sweeps) or southwell_sweeps < 0:
        raise InputError(f"southwell_sweeps must be a finite number >= 0, got {_shown(southwell_sweeps)}.")
    init = None
    if initial is not None:
        try:
            init = real_array("initial", initial, np.float32)
        except ArrayValuesError:
            raise
        except (TypeError, ValueError) as exc:
            raise InputError(f"initial must be an (H, W, 2) array of numbers ({_first_line(exc)}).") from None
        if init.shape != (height, width, 2):
            raise InputError(
                f"initial has shape {init.shape} but must be {(height, width, 2)}: a previous field of this grid."
            )
        # Its finiteness is checked by the core, in parallel, before the solve reads it (the
        # binding raises the same message as this module's other checks would).
        init = np.ascontiguousarray(init)
    return {
        "points": pts,
        "displacements": disp,
        "height": height,
        "width": width,
        "mask": mask_u8,
        "cuts": cut_list,
        "tension": float(tension),
        "tolerance": float(tolerance),
        "grid_step": int(grid_step),
        "initial": init,
        "max_cycles": None if max_cycles is None else int(max_cycles),
        "method": method,
        "southwell_sweeps": float(southwell_sweeps),
    }


def thin_plate_report(
    points: npt.ArrayLike,
    displacements: npt.ArrayLike,
    shape: Sequence[int],
    *,
    mask: npt.ArrayLike | None = None,
    cuts: Sequence[npt.ArrayLike] | None = None,
    tension: float = 0.0,
    tolerance: float = 0.01,
    grid_step: int = 1,
    initial: npt.ArrayLike | None = None,
    max_cycles: int | None = None,
    method: str = "multigrid",
    southwell_sweeps: float = 10.0,
    warm: WarmStart | None = None,
    solver: Solver | None = None,
    _off: str = "",
) -> tuple[npt.NDArray[np.float32], SolveReport]:
    """:func:`thin_plate`, also returning the :class:`SolveReport`.

    Takes the same arguments as :func:`thin_plate`, plus ``southwell_sweeps``: the work
    budget of ``method="southwell"``, in single-node relaxations per free node.

    Returns
    -------
    field : numpy.ndarray
        float32 array of shape (H, W, 2).
    report : SolveReport
        Cycles, final change, residual, sample counts, time, convergence.

    Examples
    --------
    >>> import numpy as np, inkwarp
    >>> field, report = inkwarp.thin_plate_report([[10, 10], [50, 10], [30, 40]],
    ...                                           [[2, 0], [2, 0], [2, 0]], (48, 64))
    >>> bool(np.allclose(field, [2, 0], atol=0.01)), report.converged, report.constrained_nodes
    (True, True, 3)
    """
    args = _check_args(
        points, displacements, shape, mask, cuts, tension, tolerance, grid_step, initial, max_cycles, method,
        southwell_sweeps,
    )
    if warm is not None:
        if not isinstance(warm, WarmStart):
            raise InputError(f"warm must be an inkwarp.WarmStart (or None), got {type(warm).__name__}.")
        if initial is not None:
            raise InputError("Pass initial or warm, not both: warm already starts from the earlier frames.")
    if solver is not None:
        if not isinstance(solver, Solver):
            raise InputError(f"solver must be an inkwarp.Solver (or None), got {type(solver).__name__}.")
        if warm is not None:
            raise InputError("Pass solver or warm, not both: a WarmStart keeps a solver of its own.")
    field, rep = _inkwarp.thin_plate_solve(
        args["points"],
        args["displacements"],
        args["height"],
        args["width"],
        args["mask"],
        args["cuts"],
        args["tension"],
        args["tolerance"],
        args["grid_step"],
        args["initial"],
        args["max_cycles"],
        args["method"],
        args["southwell_sweeps"],
        warm,
        off=_off,
        solver=solver,
    )
    return field, SolveReport(**rep)


def thin_plate(
    points: npt.ArrayLike,
    displacements: npt.ArrayLike,
    shape: Sequence[int],
    *,
    mask: npt.ArrayLike | None = None,
    cuts: Sequence[npt.ArrayLike] | None = None,
    tension: float = 0.0,
    tolerance: float = 0.01,
    grid_step: int = 1,
    initial: npt.ArrayLike | None = None,
    max_cycles: int | None = None,
    method: str = "multigrid",
    warm: WarmStart | None = None,
    solver: Solver | None = None,
) -> npt.NDArray[np.float32]:
    """Interpolate displacements over an image grid with the grid thin plate.

    Every point pins the grid node nearest to it (``(round(x), round(y))``, halves rounding
    up) to its displacement (several points on one node are averaged); the rest of the field
    minimises the thin-plate energy (plus ``tension`` times the membrane energy). Masked-out
    pixels and cuts separate the surface: nothing pulls across them.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Positions ``(x, y)`` in pixels: pixel centres at integers, x right, y down.
    displacements : array_like, shape (N, 2)
        ``(dx, dy)`` of each point, in pixels.
    shape : (int, int)
        ``(height, width)`` of the grid (one node per pixel).
    mask : array_like, shape (H, W), optional
        Continuity matte: nonzero pixels exist and are connected to their nonzero
        neighbours; zero pixels are holes (their displacement is 0).
    cuts : list of array_like, each shape (K, 2), optional
        Polylines that break the surface: two neighbouring pixels are disconnected when a
        cut crosses the segment between their centres.
    tension : float, default 0
        Weight of the membrane energy (0 to 1e6): 0 is a pure thin plate; larger values
        pull the surface tighter, like a rubber sheet.
    tolerance : float, default 0.01
        Stop when the estimated largest remaining error of any pixel is below this
        (pixels). At the default every pixel is within 0.05 px of the exact minimiser. A
        tolerance below 1e-7 of the largest displacement is finer than the field's float32
        resolution: the solve then never reports ``converged``. 0 runs every piece that
        needs cycles until ``max_cycles`` of them or a cycle that moves nothing, never
        converged (scenes, whose settings are for rendering, refuse it).
    grid_step : int, default 1
        Solve on every ``grid_step``-th pixel and upsample with a tensor-product cubic:
        faster, approximate (points move to the nearest coarse node).
    initial : array_like, shape (H, W, 2), optional
        A starting field, e.g. the previous frame's: the closer it is, the fewer cycles.
    warm : WarmStart, optional
        For the frames of an animation (same grid and points, moving displacements): the
        solve starts from the earlier frames' fields, extrapolated, and the ``WarmStart``
        keeps this one. Not together with ``initial``.
    solver : Solver, optional
        Kept between calls on one grid with the same points: its coarse levels are reused,
        so later calls skip their setup (same answers). Not together with ``warm``.
    max_cycles : int, optional
        Cap on the number of cycles (default 300), all of them counted (``"southwell"``: on
        its rounds), but a slow solve's probe (``SolveReport.probe_cycles``). 0 runs none and returns the start; the report says converged only where
        no cycle is needed (a piece that translates, or that one affine map fits). Through a
        ``solver``, a multigrid solve the cap stopped goes on where it stopped when the next
        call gives its answer as ``initial`` with the same points, displacements and
        tolerance: solving in steps of a few cycles (to show progress, or to stay
        responsive) is the same solve, cycle for cycle; the steps' cycles add up to its own.
    method : {"multigrid", "southwell"}, default "multigrid"
        ``"southwell"`` spends a fixed budget of greedy single-node relaxations after the
        coarse-to-fine start instead of iterating to the tolerance.

    Returns
    -------
    numpy.ndarray
        float32 array of shape (H, W, 2): ``[..., 0]`` is dx and ``[..., 1]`` dy; pixel
        ``(x, y)`` moves to ``(x + dx, y + dy)``.

    Raises
    ------
    ValueError
        For wrong shapes, non-finite numbers, empty or mismatched points, or bad options;
        the message says what to change.

    Warns
    -----
    ConvergenceWarning
        When the solve stopped before it converged (the report's ``stop``: ``max_cycles``,
        ``unsettled``, ``residual`` or ``breakdown``), as scenes warn.
    InkwarpWarning
        When every point missed the grid (off it, or on masked-out nodes: the field is zero).
        :func:`thin_plate_report` says these in its report instead.

    See Also
    --------
    thin_plate_report : the same, with the solve report.

    Examples
    --------
    Three points moved alike translate the whole grid:

    >>> import numpy as np, inkwarp
    >>> pts = [[4, 4], [28, 4], [16, 20]]
    >>> field = inkwarp.thin_plate(pts, [[3, -1]] * 3, (24, 32))
    >>> field.shape, field.dtype
    ((24, 32, 2), dtype('float32'))
    >>> bool(np.allclose(field, [3, -1], atol=0.02))
    True

    A cut keeps a pull on one side from dragging the other:

    >>> pts = [[2, 2], [2, 13], [8, 8], [13, 2], [13, 13]]
    >>> disp = [[0, 0], [0, 0], [4, 0], [0, 0], [0, 0]]
    >>> free = inkwarp.thin_plate(pts, disp, (16, 16))
    >>> cut = inkwarp.thin_plate(pts, disp, (16, 16), cuts=[[[10.5, -1], [10.5, 17]]])
    >>> float(abs(cut[8, 12, 0])) < float(abs(free[8, 12, 0]))
    True
    """
    field, report = thin_plate_report(
        points,
        displacements,
        shape,
        mask=mask,
        cuts=cuts,
        tension=tension,
        tolerance=tolerance,
        grid_step=grid_step,
        initial=initial,
        max_cycles=max_cycles,
        method=method,
        warm=warm,
        solver=solver,
    )
    # This function hides the report: what it would say against the field, it warns. (Not
    # where stopping short is the setting's own doing: southwell's budget, a tolerance of 0
    # or under the field's precision; and at a grid step over 1 a strip without a coarse
    # node still moves by its points, dropped or not.)
    if report.constrained_samples == 0 and report.dropped_samples > 0 and grid_step == 1:
        which = "the point lies" if report.dropped_samples == 1 else f"all {report.dropped_samples} points lie"
        warnings.warn(f"{which} off the grid or on masked-out nodes, so the field is zero; give points in pixels "
                      "of the grid (x across, y down)",
                      InkwarpWarning, stacklevel=2)
    elif report.stop in ("max_cycles", "unsettled", "residual", "breakdown"):
        warnings.warn(f"the thin-plate solve did not converge (stopped: {report.stop}, after {report.cycles} "
                      f"cycle{'s' if report.cycles != 1 else ''}), so the field may be off by more than 5 times "
                      "the tolerance; thin_plate_report says more", ConvergenceWarning, stacklevel=2)
    return field
