"""Animation transfer (the paper's cross-synthesis, DESIGN §7).

A source scene animates a drawing ``S0`` with keys ``Sk``; a target scene traces the same
features (same ids, kinds and control-point counts) over another picture, ``T0``. The
target's keys become ``Tk = W(Sk)``, where ``W`` is the continuous thin-plate map
(:class:`inkwarp.ThinPlateMap`) fitted from the source's rest control points to the
target's: the target performs the source's motion in its own proportions.

Rules
-----
* Every source feature except ``cut``\\ s must be in the target under the same id, with
  the same kind and the same number of rest control points; otherwise
  :class:`ValueError` names the feature.
* The map is fitted to the rest control points of all matched features.
* A matched target feature's keys are replaced by the source's, mapped (times and
  interpolation kept); target features the source lacks keep their own keys.
* The result's ``duration`` is the longer of the two scenes' (each its own, or up to and
  including its last key where it gives none); everything else (size, fps, layers,
  images, solver) is the target's.
* When ``W`` folds the source's drawing over somewhere (its Jacobian turns the plane
  over, which a matched curve traced the other way round in one of the drawings does),
  an :class:`inkwarp.InkwarpWarning` says where and names the nearest feature: the keys
  there come out mirrored.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import warnings
from pathlib import Path
from typing import Any

from inkwarp import _inkwarp
from inkwarp.errors import InkwarpWarning, InputError, MissingFileError

__all__ = ["transfer", "transfer_dict", "transfer_example"]

# Layer fields that name an image file (relative to the scene file) or hold a data: URI.
_IMAGE_FIELDS = ("image", "alpha", "continuity")


def _load(scene: Any, role: str) -> tuple[dict[str, Any], Path | None]:
    """A scene document as a dict, and the directory its relative paths start from."""
    if isinstance(scene, (str, os.PathLike)):
        from inkwarp.scene import _raise_for, _repeated_keys, read_scene_text, validate_scene

        path = Path(scene)
        if not path.exists():
            raise MissingFileError(2, f"the {role} scene does not exist", str(path))
        # The scene files' one reader and checks: a picture given as the scene, a folder,
        # bytes that are not UTF-8, and every mistake with its place, as render says them.
        text = read_scene_text(path)
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as err:
            raise InputError(f"the {role} scene {path} is not valid JSON: {err}.") from None
        # The pictures play no part in a transfer: one missing or moved is not a problem here.
        _raise_for(_repeated_keys(text) + [p for p in validate_scene(doc, base_dir=path.resolve().parent)
                    if not re.fullmatch(r"layers\[\d+\]\.(image|alpha|continuity)", p[0])], os.fspath(path))
        return doc, _folder(scene)
    if isinstance(scene, dict):
        return copy.deepcopy(scene), None
    to_dict = getattr(scene, "to_dict", None)
    if callable(to_dict):
        return to_dict(), _folder(scene)
    raise InputError(f"the {role} scene must be a path, a dict or an inkwarp.Scene; got {type(scene).__name__}.")


def _folder(scene: Any) -> Path | None:
    """The folder a scene's relative image paths start from: a scene file's, a Scene's
    ``base_dir`` (or the folder of its ``path``); None for a dict."""
    if isinstance(scene, (str, os.PathLike)):
        return Path(scene).resolve().parent
    base = None if isinstance(scene, dict) else getattr(scene, "base_dir", None) or getattr(scene, "path", None)
    if base is None:
        return None
    base = Path(base).resolve()
    return base.parent if base.suffix == ".json" else base


def _features(doc: dict[str, Any], role: str) -> list[tuple[str, str, list, list]]:
    features = doc.get("features")
    if not isinstance(features, list):
        raise InputError(f"the {role} scene has no features list.")
    out = []
    for i, f in enumerate(features):
        try:
            keys = [k["points"] for k in f.get("keys", [])]
            out.append((str(f["id"]), str(f["kind"]), f["rest"], keys))
        except (KeyError, TypeError, AttributeError):
            raise InputError(
                f"{role} features[{i}] needs an id, a kind, rest points and keys with points."
            ) from None
    return out


def _rebase_images(doc: dict[str, Any], old: Path | None, new: Path | None) -> None:
    """Rewrite relative image paths of ``doc`` from directory ``old`` to ``new`` (absolute
    when ``new`` is None)."""
    if old is None:
        return
    for layer in doc.get("layers", []) or []:
        if not isinstance(layer, dict):
            continue
        for field in _IMAGE_FIELDS:
            value = layer.get(field)
            if not isinstance(value, str) or value.startswith("data:") or os.path.isabs(value):
                continue
            absolute = (old / value).resolve()
            layer[field] = str(absolute) if new is None else os.path.relpath(absolute, new)


def transfer_dict(source: Any, target: Any, *, relative_to: str | os.PathLike | None = None) -> dict[str, Any]:
    """The target scene document with the source's animation transferred onto it.

    Parameters
    ----------
    source, target : path, dict or inkwarp.Scene
        The scene whose keys are transferred, and the scene that receives them.
    relative_to : path, optional
        Directory that the result's relative image paths should start from (where it
        will be saved). Default: they become absolute, so the result works anywhere. A
        target given as a dict keeps its paths as they are.

    Examples
    --------
    >>> import inkwarp
    >>> feature = lambda id, rest, keys=(): {"id": id, "kind": "point", "rest": rest,
    ...     "keys": [{"t": t, "points": p} for t, p in keys]}
    >>> source = {"features": [feature("a", [[0, 0]]), feature("b", [[10, 0]]),
    ...                        feature("c", [[0, 10]], [(1.0, [[2, 10]])])]}
    >>> target = {"features": [feature("a", [[0, 0]]), feature("b", [[30, 0]]),
    ...                        feature("c", [[0, 30]])]}
    >>> out = inkwarp.transfer_dict(source, target)
    >>> [round(v, 6) for v in out["features"][2]["keys"][0]["points"][0]]
    [6.0, 30.0]
    """
    from inkwarp.scene import _path_argument

    rebased = Path(_path_argument(relative_to, "relative_to")).resolve() if relative_to is not None else None
    src_doc, _ = _load(source, "source")
    tgt_doc, tgt_base = _load(target, "target")
    src_features, tgt_features = _features(src_doc, "source"), _features(tgt_doc, "target")
    name = lambda scene, role: os.fspath(scene) if isinstance(scene, (str, os.PathLike)) else f"the {role} scene"  # noqa: E731
    files = f"{name(source, 'source')} → {name(target, 'target')}"
    try:
        new_keys = _inkwarp.transfer_keys(src_features, tgt_features)
    except ValueError as err:
        # The engine names the feature and its places; the files they are in come first.
        raise InputError(f"{files}: {err}") from None
    # A target drawing whose matched points all lie at one place sends every move there.
    matched = {fid for fid, _, _, _ in src_features}
    placed = [p for fid, _, rest, _ in tgt_features if fid in matched for p in rest]
    if len(placed) > 1 and max(math.dist(p, placed[0]) for p in placed) <= 0.5:
        raise InputError(f"{files}: every control point of the target's matched features lies at "
                         f"({placed[0][0]:g}, {placed[0][1]:g}), so the map would send all of the source's "
                         "motion to that one place; trace the target's features over the parts of its picture "
                         "they match")
    by_id = {str(f["id"]): f for f in src_doc["features"]}
    # Mapped keys must fit a scene: a target drawn far larger than the source magnifies its moves.
    for i, (feature, keys) in enumerate(zip(tgt_doc["features"], new_keys)):
        for k, points in enumerate(keys or []):
            far = next((p for p in points if not all(math.isfinite(v) and abs(v) <= _inkwarp.MAX_COORD_PX for v in p)), None)
            if far is not None:
                t = float(by_id[str(feature["id"])]["keys"][k]["t"])
                raise InputError(f"{files}: the key of {feature['id']!r} at t = {t:g} s maps to ({far[0]:.6g}, "
                                 f"{far[1]:.6g}) on the target (features[{i}].keys[{k}]), farther than the "
                                 f"{_inkwarp.MAX_COORD_PX:g} px from the origin a scene may hold: the target's "
                                 "drawing is so much larger than the source's that the map magnifies its motion "
                                 "past that; match drawings of like size")
    fold = _inkwarp.transfer_fold(src_features, tgt_features)
    if fold is not None:
        warnings.warn(fold[3], InkwarpWarning, stacklevel=2)
    for feature, keys in zip(tgt_doc["features"], new_keys):
        if keys is None:
            continue
        src_keys = by_id[str(feature["id"])].get("keys", [])
        feature["keys"] = [
            {**copy.deepcopy(k), "points": [[float(x), float(y)] for x, y in pts]}
            for k, pts in zip(src_keys, keys)
        ]
    # The longer of the two lengths, each the scene's own or up to and including its last
    # key (as `Scene.duration` reads it): a target's shorter duration cut the source's motion.
    if any(isinstance(d.get("duration"), (int, float)) for d in (src_doc, tgt_doc)):
        tgt_doc["duration"] = max(_length(src_doc), _length(tgt_doc))
    _rebase_images(tgt_doc, tgt_base, rebased)
    return tgt_doc


def _length(doc: dict[str, Any]) -> float:
    """A scene document's length in seconds: its ``duration``, or up to and including its
    last key."""
    if isinstance(doc.get("duration"), (int, float)):
        return float(doc["duration"])
    last = max((float(k["t"]) for f in doc.get("features", []) for k in f.get("keys", [])), default=0.0)
    return last + 1.0 / float(doc.get("fps", 24))


def transfer(source: Any, target: Any) -> Any:
    """Transfer the source scene's animation onto the target scene's drawing.

    Parameters
    ----------
    source, target : path, dict or inkwarp.Scene
        The animated scene and the scene whose drawing receives the motion (the same
        feature ids, kinds and control-point counts; see the module notes).

    Returns
    -------
    inkwarp.Scene
        The target with the transferred keys (its own picture, layers and settings). Its
        image paths start from the target's folder, as the target's did, so
        :meth:`inkwarp.Scene.save` writes them relative to where it saves.

    Raises
    ------
    ValueError
        A source feature missing from the target, of another kind, or with another
        number of control points (the message names it); a target whose matched points
        all lie at one place; a key mapped farther than a scene may hold (1e6 px).
    """
    from inkwarp import Scene

    base = _folder(target)
    return Scene.from_dict(transfer_dict(source, target, relative_to=base), base_dir=base)


def transfer_example(examples_dir: str | os.PathLike, out_dir: str | os.PathLike) -> Path:
    """``make demo``'s transfer: the face example's animation on the cat photograph.

    Maps ``face/scene.json``'s keys onto ``transfer/cat-target.json`` (the face's drawing
    traced over the cat) and writes the result as ``transfer.json`` in ``out_dir``, its
    image paths relative to there. Returns that path.
    """
    root = Path(examples_dir)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = transfer_dict(root / "face" / "scene.json", root / "transfer" / "cat-target.json",
                        relative_to=out.resolve())
    path = out / "transfer.json"
    from inkwarp._atomic import write_text

    return write_text(path, json.dumps(doc, indent=1) + "\n", suffix=".json")
