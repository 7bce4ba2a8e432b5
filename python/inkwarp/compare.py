"""Side-by-side comparison of the interpolants on one scene (the paper's plates).

:func:`compare` computes, for each method, the frame the renderer draws and the
displacement field it draws it with; :func:`comparison_sheet` lays them out as one figure
(a row per method: the warped frame with the posed drawing over it, and the ΔX surface as
a hill-shaded height map with contours, as the paper draws its ΔX surfaces).
``inkwarp compare`` is the command-line front end.
"""

from __future__ import annotations

import json
import math
import os
import textwrap
import warnings
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np

from inkwarp.errors import InputError
from inkwarp.methods import METHODS, check_method

__all__ = ["Comparison", "checkerboard_plates", "compare", "comparison_sheet"]

TITLES = {
    "tps": "thin plate (grid, with holes and cuts)",
    "tps-exact": "thin-plate spline (continuous, no holes)",
    "triangulation": "triangulation (piecewise linear)",
    "beier-neely": "Beier–Neely (lines + Shepard points)",
}


@dataclass
class Comparison:
    """What :func:`compare` returns.

    Attributes
    ----------
    time : float
        The time compared, in seconds.
    methods : list of str
        The methods, in order.
    frames : dict of str to numpy.ndarray
        Per method the rendered frame, RGBA uint8 ``(H, W, 4)``.
    fields : dict of str to numpy.ndarray
        Per method the displacement field of the compared layer, float32 ``(H, W, 2)``.
    drawing : list of numpy.ndarray
        The posed drawing at ``time`` as ``(K, 2)`` polylines, for overlays.
    notes : dict of str to list of str
        Per method the remarks its solve made (an ignored matte, a thinning, a solve that
        did not converge).
    """

    time: float
    methods: list[str]
    frames: dict[str, np.ndarray]
    fields: dict[str, np.ndarray]
    drawing: list[np.ndarray] = field(default_factory=list)
    notes: dict[str, list[str]] = field(default_factory=dict)


def _methods(methods: Iterable[str] | str | None) -> list[str]:
    if methods is None:
        return list(METHODS)
    if isinstance(methods, str):
        methods = [m.strip() for m in methods.split(",") if m.strip()]
    elif not isinstance(methods, Iterable):
        raise InputError(f"methods must be a list of method names or a comma-separated string, such as "
                         f"'tps,triangulation'; got {type(methods).__name__} {methods!r:.40}")
    out = [check_method(m) for m in methods]
    if not out:
        raise InputError("give at least one method to compare.")
    return out


def compare(
    scene: Any,
    time: float | None = None,
    methods: Iterable[str] | str | None = None,
    *,
    layer: str | int | None = None,
    a: float | None = None,
    b: float | None = None,
    p: float | None = None,
    max_samples: int | None = None,
) -> Comparison:
    """Render ``scene`` at ``time`` with each method.

    Parameters
    ----------
    scene : inkwarp.Scene or path
        The scene (a path is loaded with :meth:`inkwarp.Scene.load`).
    time : float, optional
        Seconds (default: the scene's end, as ``inkwarp compare`` without ``--time``).
    methods : sequence of str or str, optional
        Methods to compare (a comma-separated string is accepted). Default: all of
        ``"tps"``, ``"tps-exact"``, ``"triangulation"``, ``"beier-neely"``.
    layer : str or int, optional
        The layer whose field is returned (default: the top layer that is drawn).
    a, b, p : float, optional
        Beier–Neely's weights for every layer, instead of the scene's
        ``solver.beier_neely`` (each one left out keeps the scene's value; see
        :func:`inkwarp.interpolate`).
    max_samples : int, optional
        ``tps-exact``'s sample cap for every layer, instead of the scene's
        ``solver.tps_exact.max_samples``.

    Returns
    -------
    Comparison
        Frames, fields, the posed drawing, and per method the notes of its interpolant
        (``"tps-exact ignores the continuity matte and cuts: ..."``, a thinning), each
        prefixed with its layer's name when the scene has several layers. A ``tps`` solve
        that stopped before it converged is noted there too, and said as an
        :class:`inkwarp.ConvergenceWarning`, as :meth:`Scene.render` says it.

    Raises
    ------
    inkwarp.SceneError
        When a weight or the sample cap is out of range (its path, such as
        ``solver.beier_neely.a``, says which).

    Examples
    --------
    >>> import inkwarp
    >>> scene = inkwarp.Scene.from_dict({
    ...     "inkwarp": 1, "width": 24, "height": 16, "layers": [{"name": "main"}],
    ...     "features": [{"id": "p", "kind": "point", "rest": [[8, 8]],
    ...                   "keys": [{"t": 1, "points": [[10, 8]]}]},
    ...                  {"id": "line", "kind": "polyline", "rest": [[2, 2], [20, 3]]}]})
    >>> c = inkwarp.compare(scene, 1.0, "tps-exact,beier-neely", a=4.0, max_samples=3)
    >>> c.fields["beier-neely"].shape, c.notes["tps-exact"][0][:21]
    ((16, 24, 2), 'tps-exact thinned 21 ')
    """
    from inkwarp import Scene

    if isinstance(scene, (str, os.PathLike)):
        scene = Scene.load(scene)
    elif not isinstance(scene, Scene):
        raise InputError(f"the scene must be an inkwarp.Scene or the path of a scene file; got {type(scene).__name__}")
    time = scene.duration if time is None else scene._time(time, None, frame_too=False)  # NaN and past ±27 h refused by name
    chosen = _methods(methods)
    index = _compared_layer(scene, layer)
    settings = _settings(scene, a=a, b=b, p=p, max_samples=max_samples)
    frames: dict[str, np.ndarray] = {}
    fields: dict[str, np.ndarray] = {}
    notes: dict[str, list[str]] = {}
    from inkwarp.errors import ConvergenceWarning, caller_outside

    for method in chosen:
        overrides = json.dumps({"method": method, **settings})
        with warnings.catch_warnings(record=True) as stopped:
            warnings.simplefilter("always", ConvergenceWarning)
            frame, field, said = scene._core.render_detailed(float(time), index, overrides)
        for w in stopped:  # a solve that stopped short, said at the caller's line (and noted)
            warnings.warn(w.message, w.category, stacklevel=caller_outside())
        frames[method], fields[method], notes[method] = np.asarray(frame), np.asarray(field), list(said)
    return Comparison(time=float(time), methods=chosen, frames=frames, fields=fields,
                      drawing=_drawing(scene, time), notes=notes)


def _compared_layer(scene: Any, layer: str | int | None) -> int:
    """The index of ``layer``, or of the top layer that is drawn (visible, with an image)."""
    if layer is not None:
        return int(scene._layer_index(layer))
    drawn = [j for j, d in enumerate(scene.to_dict()["layers"]) if d.get("visible", True) and d.get("image")]
    return drawn[-1] if drawn else len(scene.layers) - 1


def _settings(scene: Any, *, a: float | None, b: float | None, p: float | None,
              max_samples: int | None) -> dict[str, Any]:
    """Solver overrides for the method settings given (the scene's values for the rest)."""
    solver = scene.to_dict().get("solver", {})
    out: dict[str, Any] = {}
    weights = {k: v for k, v in (("a", a), ("b", b), ("p", p)) if v is not None}
    for name, value in weights.items():
        if not math.isfinite(float(value)):
            raise InputError(f"Beier–Neely's {name} must be a finite number; got {value}.")
    if weights:
        out["beier_neely"] = {**{"a": 1.0, "b": 2.0, "p": 0.0}, **solver.get("beier_neely", {}),
                              **{k: float(v) for k, v in weights.items()}}
    if max_samples is not None:
        if isinstance(max_samples, bool) or int(max_samples) != max_samples:
            raise InputError(f"max_samples must be a whole number; got {max_samples!r}.")
        out["tps_exact"] = {"max_samples": int(max_samples)}
    return out


def _drawing(scene: Any, time: float) -> list[np.ndarray]:
    """The posed drawing at ``time`` as polylines (every curve, each point as one row)."""
    from inkwarp import _inkwarp

    doc = json.dumps(scene.to_dict())
    return [np.asarray(line, dtype=float).reshape(-1, 2)
            for _id, kind, line in _inkwarp.posed_drawing(doc, float(time)) if kind != "cut"]


def _hillshade(dx: np.ndarray, limit: float) -> np.ndarray:
    from matplotlib import colormaps
    from matplotlib.colors import LightSource, Normalize

    light = LightSource(azdeg=315, altdeg=40)
    # Vertical exaggeration scaled to the surface, so that creases show at any amplitude.
    exaggeration = 8.0 / max(limit, 1e-6)
    return light.shade(dx, cmap=colormaps["RdBu_r"], norm=Normalize(-limit, limit),
                       blend_mode="soft", vert_exag=exaggeration)


#: A ΔX surface whose largest value is under this (pixels) is drawn flat.
FLAT_PX = 0.01


def comparison_sheet(
    comparison: Comparison,
    path: str | os.PathLike | None = None,
    *,
    title: str | None = None,
    dpi: int = 100,
    row_height: float = 3.2,
) -> Any:
    """Lay a :class:`Comparison` out as one figure, and save it to ``path`` if given.

    Each row is one method: the warped frame with the posed drawing over it (red), and
    ΔX as a hill-shaded height map (red: moved right, blue: moved left; the same colour
    scale in every row) with contour lines every ``limit / 8`` px. The method's notes
    (:attr:`Comparison.notes`) are printed under its frame.

    Returns
    -------
    matplotlib.figure.Figure
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - matplotlib is an optional dependency
        raise ImportError("comparison sheets need matplotlib: pip install 'inkwarp[compare]'") from None

    if not isinstance(comparison, Comparison):
        raise InputError(f"comparison must be what inkwarp.compare returns; got {type(comparison).__name__}")
    if isinstance(dpi, bool) or not isinstance(dpi, (int, np.integer)) or not 10 <= dpi <= 600:
        raise InputError(f"dpi must be a whole number from 10 to 600, got {dpi!r}; the default is 100")
    # A surface under a hundredth of a pixel is drawn flat: scaled up, rounding (a field at
    # rest of 1e-14 px) filled the panel with speckle.
    largest = max((float(np.abs(comparison.fields[m][..., 0]).max()) for m in comparison.methods), default=0.0)
    limit = max(largest, FLAT_PX)
    # The interpolants' remarks (an ignored matte, a thinning) go under their frames: each
    # row is taller by its lines of them (about 0.11 in each at 6.5 pt).
    # A row of text of their own, so that every row's panels are drawn at one size.
    said = {m: "\n".join(textwrap.fill(n, 52) for n in comparison.notes.get(m, [])) for m in comparison.methods}
    heights = [h for m in comparison.methods for h in ([row_height] + ([0.11 * (said[m].count("\n") + 1) + 0.05] if said[m] else []))]
    fig = Figure(figsize=(2 * row_height * 1.05 + 0.6, sum(heights) + 0.6), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(len(heights), 2, height_ratios=heights)
    levels = np.linspace(-limit, limit, 17)
    at = 0
    for r, method in enumerate(comparison.methods):
        frame, dx = comparison.frames[method], comparison.fields[method][..., 0]
        ax_img, ax_dx = fig.add_subplot(grid[at, 0]), fig.add_subplot(grid[at, 1])
        if said[method]:
            ax_note = fig.add_subplot(grid[at + 1, :])
            ax_note.axis("off")
            ax_note.text(0.0, 1.0, said[method], fontsize=6.5, color="#7f3f00", va="top", ha="left", transform=ax_note.transAxes)
        at += 2 if said[method] else 1
        ax_img.imshow(_checker_under(frame), interpolation="nearest")
        for poly in comparison.drawing:
            if len(poly) == 1:
                ax_img.plot(poly[:, 0], poly[:, 1], "o", ms=3, color="#d62728")
            else:
                ax_img.plot(poly[:, 0], poly[:, 1], "-", lw=1.0, color="#d62728")
        ax_img.set_xlim(-0.5, frame.shape[1] - 0.5)
        ax_img.set_ylim(frame.shape[0] - 0.5, -0.5)
        ax_img.set_ylabel(TITLES.get(method, method), fontsize=8)
        flat = float(np.abs(dx).max()) < FLAT_PX
        ax_dx.imshow(_hillshade(np.zeros_like(dx) if flat else dx, limit), interpolation="nearest")
        if not flat:
            ax_dx.contour(dx, levels=levels, colors="k", linewidths=0.4, alpha=0.6)
        for ax in (ax_img, ax_dx):
            ax.set_xticks([])
            ax.set_yticks([])
        if r == 0:
            ax_img.set_title("warped frame and drawing", fontsize=9)
            scale = "flat" if largest < FLAT_PX else f"±{limit:.1f} px" if limit >= 0.1 else f"±{limit:.2f} px"
            ax_dx.set_title(f"ΔX surface ({scale})", fontsize=9)
    fig.suptitle(title or f"t = {comparison.time:g} s", fontsize=10)
    if path is not None:
        fig.savefig(os.fspath(path), dpi=dpi)
    return fig


def _checker_under(rgba: np.ndarray, cell: int = 8) -> np.ndarray:
    """``rgba`` composited over a light checkerboard, so transparent holes show."""
    h, w = rgba.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    board = np.where(((xs // cell) + (ys // cell)) % 2 == 0, 0.93, 0.80)[..., None]
    if rgba.shape[-1] == 3:
        return rgba.astype(float) / 255.0
    alpha = rgba[..., 3:4].astype(float) / 255.0
    return rgba[..., :3].astype(float) / 255.0 * alpha + board * (1 - alpha)


def sheet_from_arrays(
    frames: dict[str, np.ndarray],
    fields: dict[str, np.ndarray],
    path: str | os.PathLike | None = None,
    *,
    drawing: Sequence[Any] = (),
    time: float = 0.0,
    title: str | None = None,
) -> Any:
    """:func:`comparison_sheet` for frames and fields computed elsewhere."""
    comparison = Comparison(time=time, methods=list(frames), frames=frames, fields=fields,
                            drawing=[np.asarray(p, dtype=float).reshape(-1, 2) for p in drawing])
    return comparison_sheet(comparison, path, title=title)


def checkerboard_plates(examples_dir: str | os.PathLike, out_dir: str | os.PathLike, *, time: float = 2.0,
                        dpi: int = 80) -> list[Any]:
    """The paper's plates for ``examples/checkerboard-hole``: one sheet with triangulation,
    Beier–Neely, and the thin plate without and with the hole, at ``time``.

    Writes ``checkerboard-plates.png`` into ``out_dir`` and returns its path.
    """
    from pathlib import Path

    from inkwarp import Scene

    root = Path(examples_dir) / "checkerboard-hole"
    with_hole = Scene.load(root / "with-hole.json")
    without = Scene.load(root / "without-hole.json")
    rows = [
        ("triangulation", with_hole, "triangulation"),
        ("Beier–Neely", with_hole, "beier-neely"),
        ("thin plate, without the hole", without, "tps"),
        ("thin plate, with the hole", with_hole, "tps"),
    ]
    frames, fields, notes = {}, {}, {}
    for label, scene, method in rows:
        single = compare(scene, time, [method])
        frames[label], fields[label] = single.frames[method], single.fields[method]
        notes[label] = single.notes[method]
    comparison = Comparison(time=time, methods=[r[0] for r in rows], frames=frames, fields=fields,
                            drawing=_drawing(with_hole, time), notes=notes)
    out = Path(out_dir) / "checkerboard-plates.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    comparison_sheet(comparison, out, title=f"closing a gap in a checkerboard, t = {time:g} s", dpi=dpi)
    return [out]
