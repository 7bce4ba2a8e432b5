"""Drawings from SVG: the paths, lines, polylines, polygons, rectangles, circles and ellipses
of an SVG traced over a picture (in Inkscape, Illustrator, ...) become a scene's features.

How each element becomes a feature:

- a closed, filled shape (a closed path, a polygon, a rectangle, a circle, an ellipse, with
  a fill that is not ``none``, ``transparent`` or of opacity 0) becomes a ``region``;
- an open path becomes a ``spline`` when it has curves (its Béziers are fitted by the
  centripetal Catmull-Rom curve that the engine draws, within 0.25 px) or a ``polyline``
  when it is made of straight segments; a closed shape without fill becomes a closed
  ``spline`` or ``polyline``;
- an element whose ``id`` or ``class`` (or a group around it, by id, class or Inkscape
  layer name) has the word ``cut`` or ``cuts`` (``neck-cut``, ``cut2``, ``neckCut``; not
  ``cute`` or ``haircut``) becomes a ``cut`` (an open polyline, curves flattened within
  0.25 px; a closed shape's back to its start), and a note names the features that did;
- a single-point marker (a path of one point, or a circle or ellipse of radius at most
  3 px) becomes a ``point`` at its centre.

Fills are read from presentation attributes, ``<style>`` sheets (rules on element, class
and id selectors, as Illustrator writes them) and ``style`` attributes, in CSS's order.
The SVG's ``viewBox`` (or, without one, its ``width`` and ``height``) is stretched over the
picture, and every ``transform`` is applied. SVG puts pixel ``c`` between ``c`` and
``c + 1`` while a scene puts its centre at ``c``, so SVG coordinates are moved by half a
pixel up and left. Each feature takes its element's ``id`` (a path of several pieces gives
``ID``, ``ID-2``, ...; an element without one gets ``KIND-N``).

Examples
--------
>>> import tempfile
>>> from pathlib import Path
>>> svg = Path(tempfile.mkdtemp()) / "drawing.svg"
>>> _ = svg.write_text('''<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 64 48">
...   <polyline id="arm" points="10.5,10.5 30.5,20.5 50.5,10.5" fill="none"/>
...   <circle id="eye" cx="20.5" cy="30.5" r="2"/>
... </svg>''')
>>> features, notes = read_drawing(svg, 64, 48)
>>> [(f["id"], f["kind"], f["rest"]) for f in features]
[('arm', 'polyline', [[10.0, 10.0], [30.0, 20.0], [50.0, 10.0]]), ('eye', 'point', [[20.0, 30.0]])]
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from inkwarp.errors import InputError, MissingFileError

__all__ = ["TOLERANCE_PX", "read_drawing"]

#: How far a fitted spline or a flattened polyline may stray from the SVG's curve.
TOLERANCE_PX = 0.25
#: Circles and ellipses up to this radius (in picture pixels) are point markers.
MARKER_RADIUS_PX = 3.0

SVG_NS = "{http://www.w3.org/2000/svg}"
INKSCAPE_LABEL = "{http://www.inkscape.org/namespaces/inkscape}label"
SHAPES = ("path", "line", "polyline", "polygon", "rect", "circle", "ellipse")
SKIPPED = ("defs", "clipPath", "mask", "symbol", "marker", "pattern", "metadata", "title",
           "desc", "style", "linearGradient", "radialGradient", "filter")

Affine = np.ndarray  # 2x3: [[a, c, e], [b, d, f]]
Point = tuple[float, float]


class _Subpath:
    """Cubic Bézier segments (lines as cubics with their handles at thirds)."""

    def __init__(self, start: Point) -> None:
        self.start = start
        self.segments: list[tuple[Point, Point, Point, Point]] = []
        self.straight: list[bool] = []
        self.closed = False

    @property
    def end(self) -> Point:
        return self.segments[-1][3] if self.segments else self.start

    def line(self, p: Point) -> None:
        a = self.end
        self.segments.append((a, _lerp(a, p, 1 / 3), _lerp(a, p, 2 / 3), p))
        self.straight.append(True)

    def cubic(self, c1: Point, c2: Point, p: Point) -> None:
        self.segments.append((self.end, c1, c2, p))
        self.straight.append(False)


def _lerp(a: Point, b: Point, t: float) -> Point:
    return (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t)


# ---- reading the file ------------------------------------------------------------------

def read_drawing(path: str | os.PathLike[str], width: int, height: int
                 ) -> tuple[list[dict[str, Any]], list[str]]:
    """The features of an SVG drawing traced over a ``width`` × ``height`` picture.

    Returns
    -------
    (features, notes)
        Features in the scene format (in document order) and notes about what was
        skipped or approximated.

    Raises
    ------
    inkwarp.errors.MissingFileError, inkwarp.InputError
        A missing file, a file that is not SVG, bad path data (naming the element), or an
        SVG without anything to turn into features.
    """
    source = Path(os.fspath(path))
    if not source.exists():
        raise MissingFileError(2, "No such file or directory", str(source))
    try:
        root = ET.parse(source).getroot()
    except ET.ParseError as err:
        raise InputError(f"{source}: not a readable SVG file ({err}); save it again as "
                         "plain SVG") from None
    if _tag(root) != "svg":
        raise InputError(f"{source}: the file's root element is <{_tag(root)}>, not <svg>; "
                         "give an SVG drawing")
    notes: list[str] = []
    rules = _stylesheet(root, source, notes)
    root_transform = _viewport(root, width, height, source, notes)
    # A scene's pixel centre c is SVG's c + 0.5.
    root_transform = _compose(_translate(-0.5, -0.5), root_transform)
    features: list[dict[str, Any]] = []
    ids: set[str] = set()
    counts: dict[str, int] = {}
    hidden: list[str] = []  # what display or visibility hides, named for the error if nothing shows

    def visit(element: ET.Element, transform: Affine, fill: str, opacity: str, cut: bool, shown: bool) -> None:
        tag = _tag(element)
        if tag in SKIPPED:
            return
        style = _style(element, rules)
        if style.get("display") == "none":
            hidden.append(_name(element))
            notes.append(f"{source}: <{tag}> {_name(element)} is hidden (display: none) and "
                         "left out")
            return
        # Visibility inherits, and a child may show itself again (unlike display: none); a
        # value CSS does not know is ignored, as CSS ignores it.
        visibility = style.get("visibility", "").lower()
        if visibility in ("visible", "hidden", "collapse") and shown != (visibility == "visible"):
            shown = visibility == "visible"
            if not shown:
                hidden.append(_name(element))
                notes.append(f"{source}: <{tag}> {_name(element)} is hidden (visibility: {visibility}) and left out"
                             + (", with what it holds but shapes set to visibility: visible" if len(element) else ""))
        here = _compose(transform, _parse_transform(element.get("transform", ""), source,
                                                    element))
        fill = style.get("fill", fill)
        opacity = style.get("fill-opacity", opacity)
        words = _words(element)
        cut = cut or _says_cut(words)
        if not cut and any(w.startswith("cut") or w.endswith("cut") for w in words):
            near_cuts.append(element.get("id") or element.get("class") or element.get(INKSCAPE_LABEL) or tag)
        if tag in ("text", "image", "foreignObject"):
            why = {"text": "text makes no feature (Inkscape: Path > Object to Path turns it into paths)",
                   "image": "a picture in the drawing makes no feature (the scene's pictures are its layers)"
                   }.get(tag, "embedded content makes no feature")
            notes.append(f"{source}: <{tag}> {_name(element)} is left out: {why}")
            return
        if tag == "use":
            notes.append(f"{source}: <use> {_name(element)} is left out; unlink the clone "
                         "(Inkscape: Edit > Clone > Unlink Clone) to trace it")
            return
        if tag in SHAPES and shown:
            subpaths = _shape_subpaths(element, tag, source)
            filled = _painted(fill, opacity)
            base = element.get("id") or ""
            for index, subpath in enumerate(subpaths):
                feature = _feature(subpath, here, filled, cut, tag)
                if feature is None:
                    continue
                name = base if base and index == 0 else (
                    f"{base}-{index + 1}" if base else "")
                if not name:
                    counts[feature["kind"]] = counts.get(feature["kind"], 0) + 1
                    name = f"{feature['kind']}-{counts[feature['kind']]}"
                wanted = name
                while name in ids:
                    name += "-2"
                if name != wanted:
                    notes.append(f"{source}: the id {wanted!r} is taken by an earlier feature; "
                                 f"this {tag} is {name!r}")
                ids.add(name)
                features.append({"id": name, **feature})
                if feature["kind"] == "cut":
                    cuts.append(name)
            if len(subpaths) > 1:
                notes.append(f"{source}: <{tag}> {_name(element)} has {len(subpaths)} "
                             "pieces, each a feature of its own")
        for child in element:
            visit(child, here, fill, opacity, cut, shown)

    cuts: list[str] = []
    near_cuts: list[str] = []  # names with the letters "cut" that are not cuts
    top = _style(root, rules)
    root_shown = top.get("visibility", "").lower() not in ("hidden", "collapse")
    if not root_shown:
        hidden.append("<svg>")
        notes.append(f"{source}: the <svg> is hidden (visibility: {top['visibility'].lower()}): its shapes are left out "
                     "but those set to visibility: visible")
    for child in root:
        visit(child, root_transform, top.get("fill", "black"), top.get("fill-opacity", "1"), _says_cut(_words(root)),
              root_shown)
    if not features and hidden:
        raise InputError(f"{source}: every shape of the SVG is hidden (display: none, or visibility: hidden or "
                         f"collapse: {', '.join(hidden[:3])}{', ...' if len(hidden) > 3 else ''}), so none makes a "
                         "feature; show the layers that hold the tracing and save again")
    if not features:
        raise InputError(f"{source}: the SVG has no paths, lines, polylines, polygons, "
                         "rectangles or circles to make features of; trace the features "
                         "with the pen or shape tools and save the drawing as SVG")
    if cuts:
        notes.append(f"{source}: {', '.join(map(repr, cuts))} "
                     f"{'is a cut' if len(cuts) == 1 else 'are cuts'} (the word 'cut' in an id, "
                     "class or layer name): the surface tears along them and they move nothing")
    near_cuts = list(dict.fromkeys(near_cuts))  # one name once, and counted once
    if near_cuts:
        notes.append(f"{source}: {', '.join(map(repr, near_cuts))} "
                     f"{'has' if len(near_cuts) == 1 else 'have'} the letters 'cut' in a name but "
                     f"{'is' if len(near_cuts) == 1 else 'are'} not a cut: a cut is named by the word "
                     "(neck-cut, cut2, neckCut)")
    return features, notes


def _tag(element: ET.Element) -> str:
    return element.tag.rsplit("}", 1)[-1] if isinstance(element.tag, str) else ""


def _name(element: ET.Element) -> str:
    return f"id={element.get('id')!r}" if element.get("id") else "(without id)"


#: The properties read from an element's style: whether it shows, and its fill.
STYLED = ("fill", "fill-opacity", "display", "visibility")

#: A style sheet rule: (specificity, selector's tag, its classes, its id, its declarations,
#: its ``!important`` ones).
_Rule = tuple[tuple[int, int, int], str, frozenset[str], str, dict[str, str], dict[str, str]]

#: A value that takes the parent's (the key dropped, so the inherited fill stands), and
#: what ``initial`` sets.
_INHERITED = ("inherit", "unset")
_INITIAL = {"fill": "black", "fill-opacity": "1", "display": "inline", "visibility": "visible"}


def _declarations(text: str) -> tuple[dict[str, str], dict[str, str]]:
    """The declarations of ``text`` that inkwarp reads: ``(normal, important)``."""
    out: tuple[dict[str, str], dict[str, str]] = ({}, {})
    for item in text.split(";"):
        key, _, value = item.partition(":")
        key, value = key.strip().lower(), value.strip()
        important = re.search(r"!\s*important\s*$", value, flags=re.I)
        value = value[:important.start()].strip() if important else value
        if key in STYLED and value:
            out[bool(important)][key] = value
    return out


def _stylesheet(root: ET.Element, source: Path, notes: list[str]) -> list[_Rule]:
    """The rules of the drawing's ``<style>`` elements that set a fill or display, in
    the order CSS applies them (by specificity, then document order). At-rules are left
    out (``@media`` blocks and their rules too); selectors other than an element, class
    or id (or those joined: ``path.cls-1``) get a note."""
    rules: list[_Rule] = []
    text = " ".join("".join(e.itertext()) for e in root.iter() if _tag(e) == "style")
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    at_rules = _AT_BLOCK.findall(text)
    if any(any(_declarations(body)) for block in at_rules for body in re.findall(r"\{([^{}]*)\}", block)):
        notes.append(f"{source}: style rules inside @media or @supports blocks are not applied; "
                     "move the fills the drawing needs out of them")
    text = re.sub(_AT_BLOCK.pattern + r"|@[\w-]+[^;{}]*;", " ", text)
    for selectors, body in re.findall(r"([^{}]*)\{([^{}]*)\}", text):
        normal, important = _declarations(body)
        for selector in filter(None, (part.strip() for part in selectors.split(",")) if normal or important else ()):
            match = re.fullmatch(r"(\*|[A-Za-z][\w-]*)?((?:\.[\w-]+)*)(#[\w-]+)?((?:\.[\w-]+)*)", selector)
            if match is None:
                notes.append(f"{source}: the style rule {selector!r} is not applied (inkwarp reads "
                             "rules on an element, a class or an id); give the shapes a class")
                continue
            tag, classes = match[1] or "*", frozenset((match[2] + match[4]).split(".")) - {""}
            ident = (match[3] or "#")[1:]
            rules.append(((int(bool(ident)), len(classes), int(tag != "*")), tag, classes, ident, normal, important))
    return sorted(rules, key=lambda rule: rule[0])  # stable: document order within a specificity


def _style(element: ET.Element, rules: list[_Rule]) -> dict[str, str]:
    """What the element's style says of :data:`STYLED`, in CSS's order: presentation
    attributes, the style sheet's matching rules, the ``style`` attribute, then the
    ``!important`` rules and the ``style`` attribute's ``!important`` declarations. A
    property that inherits is left out (its parent's stands)."""
    out = {key: element.get(key, "").strip() for key in STYLED if element.get(key, "").strip()}
    classes, tag = set(element.get("class", "").split()), _tag(element)
    matching = [rule for rule in rules
                if rule[1] in ("*", tag) and rule[2] <= classes and rule[3] in ("", element.get("id"))]
    inline = _declarations(element.get("style", ""))
    for declared in [rule[4] for rule in matching] + [inline[0]] + [rule[5] for rule in matching] + [inline[1]]:
        out.update(declared)
    for key, value in list(out.items()):
        if value.lower() in _INHERITED:
            del out[key]
        elif value.lower() == "initial":
            out[key] = _INITIAL[key]
    return out


def _painted(fill: str, opacity: str) -> bool:
    """Whether a shape with this ``fill`` and ``fill-opacity`` shows a fill."""
    fill = fill.strip().lower().replace(" ", "")
    try:
        opaque = float(opacity.strip().rstrip("%")) > 0
    except ValueError:
        opaque = True
    clear = (fill in ("none", "transparent") or re.fullmatch(r"#[0-9a-f]{3}0|#[0-9a-f]{6}00", fill)
             or re.fullmatch(r"(rgba|hsla)\(.*,0*\.?0*%?\)", fill))
    return opaque and not clear


def _names(element: ET.Element) -> str:
    return " ".join(element.get(key, "") for key in ("id", "class", INKSCAPE_LABEL))


def _words(element: ET.Element) -> list[str]:
    """The words of the element's id, class and Inkscape layer name, in small letters (split
    at anything but a letter, and at a capital after a small letter)."""
    return re.split(r"[^a-z]+", re.sub(r"([a-z])([A-Z])", r"\1 \2", _names(element)).lower())


def _says_cut(words: list[str]) -> bool:
    """Whether an element's words (:func:`_words`: its id, class and Inkscape layer name) have
    the word ``cut`` or ``cuts``."""
    return any(word in ("cut", "cuts") for word in words)


_UNITS = {"": 1.0, "px": 1.0, "pt": 96 / 72, "pc": 16.0, "mm": 96 / 25.4, "cm": 96 / 2.54,
          "in": 96.0}


def _length(text: str | None) -> float | None:
    if not text:
        return None
    match = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-z%]*)\s*", text)
    if not match or match.group(2) not in _UNITS:
        return None
    return float(match.group(1)) * _UNITS[match.group(2)]


def _viewport(root: ET.Element, width: int, height: int, source: Path, notes: list[str]
              ) -> Affine:
    """The map from the SVG's user units to the picture's pixels (SVG's pixel corners)."""
    box = root.get("viewBox")
    if box:
        numbers = _numbers(box)
        if len(numbers) != 4 or numbers[2] <= 0 or numbers[3] <= 0:
            raise InputError(f"{source}: viewBox={box!r} is not 'min-x min-y width height' "
                             "with a positive width and height; fix the svg element's viewBox")
        x0, y0, w, h = numbers
    else:
        x0, y0 = 0.0, 0.0
        w = _length(root.get("width")) or float(width)
        h = _length(root.get("height")) or float(height)
    sx, sy = width / w, height / h
    if abs(sx - sy) > 0.01 * max(sx, sy):
        notes.append(f"{source}: the drawing is {w:g}x{h:g} but the picture is {width}x{height}; "
                     "it is stretched to fit (trace over the picture at its own size to avoid "
                     "this)")
    return np.array([[sx, 0.0, -x0 * sx], [0.0, sy, -y0 * sy]])


#: An at-rule's block (``@media ... { rules }``), one level of rules inside.
_AT_BLOCK = re.compile(r"@[\w-]+[^;{}]*\{(?:[^{}]*\{[^{}]*\})*[^{}]*\}")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _numbers(text: str) -> list[float]:
    return [float(x) for x in _NUMBER.findall(text)]


def _translate(x: float, y: float) -> Affine:
    return np.array([[1.0, 0.0, x], [0.0, 1.0, y]])


def _compose(outer: Affine, inner: Affine) -> Affine:
    """``outer ∘ inner``."""
    a = np.vstack([outer, [0.0, 0.0, 1.0]]) @ np.vstack([inner, [0.0, 0.0, 1.0]])
    return a[:2]


def _parse_transform(text: str, source: Path, element: ET.Element) -> Affine:
    result = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    for name, args in re.findall(r"(matrix|translate|scale|rotate|skewX|skewY)\s*\(([^)]*)\)",
                                 text):
        v = _numbers(args)
        try:
            if name == "matrix":
                a, b, c, d, e, f = v
                m = np.array([[a, c, e], [b, d, f]])
            elif name == "translate":
                m = _translate(v[0], v[1] if len(v) > 1 else 0.0)
            elif name == "scale":
                sx = v[0]
                sy = v[1] if len(v) > 1 else sx
                m = np.array([[sx, 0.0, 0.0], [0.0, sy, 0.0]])
            elif name == "rotate":
                t = math.radians(v[0])
                m = np.array([[math.cos(t), -math.sin(t), 0.0], [math.sin(t), math.cos(t), 0.0]])
                if len(v) == 3:
                    m = _compose(_translate(v[1], v[2]), _compose(m, _translate(-v[1], -v[2])))
            elif name == "skewX":
                m = np.array([[1.0, math.tan(math.radians(v[0])), 0.0], [0.0, 1.0, 0.0]])
            else:
                m = np.array([[1.0, 0.0, 0.0], [math.tan(math.radians(v[0])), 1.0, 0.0]])
        except (ValueError, IndexError):
            raise InputError(f"{source}: <{_tag(element)}> {_name(element)}: transform "
                             f"{name}({args}) has the wrong number of values; fix the "
                             "element's transform") from None
        result = _compose(result, m)
    return result


# ---- shapes to subpaths ----------------------------------------------------------------

def _attr(element: ET.Element, key: str, source: Path, default: float | None = None) -> float:
    value = _length(element.get(key))
    if value is None:
        if default is not None and element.get(key) is None:
            return default
        raise InputError(f"{source}: <{_tag(element)}> {_name(element)}: {key}="
                         f"{element.get(key)!r} is not a length; give a number")
    return value


def _shape_subpaths(element: ET.Element, tag: str, source: Path) -> list[_Subpath]:
    if tag == "path":
        return _parse_path(element.get("d", ""), source, element)
    if tag == "line":
        s = _Subpath((_attr(element, "x1", source, 0.0), _attr(element, "y1", source, 0.0)))
        s.line((_attr(element, "x2", source, 0.0), _attr(element, "y2", source, 0.0)))
        return [s]
    if tag in ("polyline", "polygon"):
        v = _numbers(element.get("points", ""))
        if len(v) < 2 or len(v) % 2:
            raise InputError(f"{source}: <{tag}> {_name(element)}: points="
                             f"{element.get('points')!r} is not a list of x,y pairs; fix it")
        pts = list(zip(v[::2], v[1::2]))
        s = _Subpath(pts[0])
        for p in pts[1:]:
            s.line(p)
        s.closed = tag == "polygon"
        return [s]
    if tag == "rect":
        x, y = _attr(element, "x", source, 0.0), _attr(element, "y", source, 0.0)
        w, h = _attr(element, "width", source), _attr(element, "height", source)
        s = _Subpath((x, y))
        for p in ((x + w, y), (x + w, y + h), (x, y + h)):
            s.line(p)
        s.closed = True
        return [s]
    # circle, ellipse: four quarter arcs
    cx, cy = _attr(element, "cx", source, 0.0), _attr(element, "cy", source, 0.0)
    if tag == "circle":
        rx = ry = _attr(element, "r", source)
    else:
        rx, ry = _attr(element, "rx", source), _attr(element, "ry", source)
    k = 4 / 3 * (math.sqrt(2) - 1)
    s = _Subpath((cx + rx, cy))
    s.cubic((cx + rx, cy + k * ry), (cx + k * rx, cy + ry), (cx, cy + ry))
    s.cubic((cx - k * rx, cy + ry), (cx - rx, cy + k * ry), (cx - rx, cy))
    s.cubic((cx - rx, cy - k * ry), (cx - k * rx, cy - ry), (cx, cy - ry))
    s.cubic((cx + k * rx, cy - ry), (cx + rx, cy - k * ry), (cx + rx, cy))
    s.closed = True
    s.marker_centre = (cx, cy)  # type: ignore[attr-defined]
    return [s]


_PATH_TOKEN = re.compile(r"([MmLlHhVvCcSsQqTtAaZz])|([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")
_ARGS = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7, "Z": 0}


def _parse_path(d: str, source: Path, element: ET.Element) -> list[_Subpath]:
    """The subpaths of SVG path data, all commands, relative and absolute."""
    def bad(why: str) -> ValueError:
        return ValueError(f"{source}: <path> {_name(element)}: d={d[:60]!r}: {why}; fix the "
                          "path data (or redraw the path)")

    leftover = _PATH_TOKEN.sub(" ", d.replace(",", " "))
    if leftover.strip():
        raise bad(f"unexpected {leftover.strip()[:10]!r}")
    tokens = [(c, float(n) if n else None) for c, n in _PATH_TOKEN.findall(d)]
    subpaths: list[_Subpath] = []
    current: _Subpath | None = None
    pos: Point = (0.0, 0.0)
    start: Point = (0.0, 0.0)
    last_control: Point | None = None
    last_command = ""
    i = 0
    command = ""
    while i < len(tokens):
        letter, _ = tokens[i]
        if letter:
            command = letter
            i += 1
            if command in "Zz":
                if current is not None:
                    current.closed = True
                    if math.dist(current.end, current.start) > 1e-9:
                        current.line(current.start)
                    pos = current.start
                    current = None
                last_command = command
                last_control = None
                continue
        elif not command:
            raise bad("path data must start with a command such as M")
        n = _ARGS[command.upper()]
        args = []
        for _ in range(n):
            if i >= len(tokens) or tokens[i][0]:
                raise bad(f"command {command} needs {n} numbers")
            args.append(tokens[i][1])
            i += 1
        rel = command.islower()
        up = command.upper()
        ox, oy = pos if rel else (0.0, 0.0)

        def p(k: int) -> Point:
            return (args[k] + ox, args[k + 1] + oy)

        if up == "M":
            pos = p(0)
            start = pos
            current = _Subpath(pos)
            subpaths.append(current)
            command = "l" if rel else "L"  # further pairs are lines
            last_control = None
            last_command = "M"
            continue
        if current is None:  # drawing after Z starts at the subpath's start
            current = _Subpath(pos if last_command not in "Zz" else start)
            subpaths.append(current)
        if up == "L":
            pos = p(0)
            current.line(pos)
            last_control = None
        elif up == "H":
            pos = (args[0] + ox, pos[1])
            current.line(pos)
            last_control = None
        elif up == "V":
            pos = (pos[0], args[0] + oy)
            current.line(pos)
            last_control = None
        elif up == "C":
            c1, c2, pos = p(0), p(2), p(4)
            current.cubic(c1, c2, pos)
            last_control = c2
        elif up == "S":
            c1 = _reflect(last_control, pos) if last_command.upper() in "CS" else pos
            c2, pos = p(0), p(2)
            current.cubic(c1, c2, pos)
            last_control = c2
        elif up in "QT":
            if up == "Q":
                q, end = p(0), p(2)
            else:
                q = _reflect(last_control, pos) if last_command.upper() in "QT" else pos
                end = p(0)
            current.cubic(_lerp(pos, q, 2 / 3), _lerp(end, q, 2 / 3), end)
            pos = end
            last_control = q
        elif up == "A":
            end = (args[5] + ox, args[6] + oy)
            for c1, c2, e in _arc(pos, args[0], args[1], args[2], args[3] != 0, args[4] != 0,
                                  end):
                current.cubic(c1, c2, e)
            pos = end
            last_control = None
        last_command = command
    if not tokens:
        return []
    return subpaths


def _reflect(control: Point | None, about: Point) -> Point:
    if control is None:
        return about
    return (2 * about[0] - control[0], 2 * about[1] - control[1])


def _arc(p0: Point, rx: float, ry: float, angle_deg: float, large: bool, sweep: bool,
         p1: Point) -> list[tuple[Point, Point, Point]]:
    """An SVG elliptical arc as cubic Béziers of at most 90° each (SVG 1.1 appendix F.6)."""
    if math.dist(p0, p1) < 1e-12:
        return []
    rx, ry = abs(rx), abs(ry)
    if rx == 0 or ry == 0:
        return [(_lerp(p0, p1, 1 / 3), _lerp(p0, p1, 2 / 3), p1)]
    phi = math.radians(angle_deg)
    cos, sin = math.cos(phi), math.sin(phi)
    dx, dy = (p0[0] - p1[0]) / 2, (p0[1] - p1[1]) / 2
    x1 = cos * dx + sin * dy
    y1 = -sin * dx + cos * dy
    scale = x1 * x1 / (rx * rx) + y1 * y1 / (ry * ry)
    if scale > 1:
        rx, ry = rx * math.sqrt(scale), ry * math.sqrt(scale)
    num = rx * rx * ry * ry - rx * rx * y1 * y1 - ry * ry * x1 * x1
    den = rx * rx * y1 * y1 + ry * ry * x1 * x1
    coef = math.sqrt(max(num / den, 0.0)) if den else 0.0
    if large == sweep:
        coef = -coef
    cxp, cyp = coef * rx * y1 / ry, -coef * ry * x1 / rx
    cx = cos * cxp - sin * cyp + (p0[0] + p1[0]) / 2
    cy = sin * cxp + cos * cyp + (p0[1] + p1[1]) / 2

    def angle(ux: float, uy: float, vx: float, vy: float) -> float:
        return math.atan2(ux * vy - uy * vx, ux * vx + uy * vy)

    t0 = angle(1, 0, (x1 - cxp) / rx, (y1 - cyp) / ry)
    dt = angle((x1 - cxp) / rx, (y1 - cyp) / ry, (-x1 - cxp) / rx, (-y1 - cyp) / ry)
    if not sweep and dt > 0:
        dt -= 2 * math.pi
    elif sweep and dt < 0:
        dt += 2 * math.pi
    pieces = max(1, math.ceil(abs(dt) / (math.pi / 2) - 1e-9))
    step = dt / pieces
    k = 4 / 3 * math.tan(step / 4)

    def at(t: float) -> tuple[Point, Point]:
        ex, ey = rx * math.cos(t), ry * math.sin(t)
        tx, ty = -rx * math.sin(t), ry * math.cos(t)
        point = (cx + cos * ex - sin * ey, cy + sin * ex + cos * ey)
        tangent = (cos * tx - sin * ty, sin * tx + cos * ty)
        return point, tangent

    out = []
    for j in range(pieces):
        a, b = t0 + j * step, t0 + (j + 1) * step
        pa, ta = at(a)
        pb, tb = at(b)
        if j == pieces - 1:
            pb = p1
        out.append(((pa[0] + k * ta[0], pa[1] + k * ta[1]),
                    (pb[0] - k * tb[0], pb[1] - k * tb[1]), pb))
    return out


# ---- subpaths to features --------------------------------------------------------------

def _apply(transform: Affine, points: np.ndarray) -> np.ndarray:
    return points @ transform[:, :2].T + transform[:, 2]


def _feature(subpath: _Subpath, transform: Affine, filled: bool, cut: bool, tag: str
             ) -> dict[str, Any] | None:
    segments = [np.array(s, dtype=np.float64) for s in subpath.segments]
    segments = [_apply(transform, s) for s in segments]
    segments = [s for s in segments if np.abs(s - s[0]).max() > 1e-9]
    centre = getattr(subpath, "marker_centre", None)
    if centre is not None and not cut:
        scale = math.sqrt(abs(np.linalg.det(transform[:, :2])))
        radius = max(math.dist(subpath.start, (centre[0], centre[1])), 0.0) * scale
        if radius <= MARKER_RADIUS_PX:
            c = _apply(transform, np.array([centre], np.float64))[0]
            return {"kind": "point", "rest": [_rounded(c)]}
    if not segments:
        start = _apply(transform, np.array([subpath.start], np.float64))[0]
        return None if cut else {"kind": "point", "rest": [_rounded(start)]}
    straight = all(
        np.abs(_cross(s[1:] - s[0], s[3] - s[0])).max() <= 1e-9 * max(1.0, np.abs(s).max())
        for s in segments)
    closed = subpath.closed
    if cut:
        # A cut is an open polyline (DESIGN §3): a closed shape's runs back to its start, so
        # that its closing side (a rectangle's fourth) tears too.
        points = list(_flatten(segments))
        if closed and len(points) > 2 and not np.allclose(points[0], points[-1]):
            points.append(points[0])
        return {"kind": "cut", "rest": [_rounded(p) for p in points]}
    if straight:
        points = [segments[0][0]] + [s[3] for s in segments]
        if closed and np.allclose(points[0], points[-1]):
            points = points[:-1]
        rest = [_rounded(p) for p in points]
        if closed and filled and len(rest) >= 3:
            return {"kind": "region", "rest": rest}
        return {"kind": "polyline", "rest": rest, **({"closed": True} if closed else {})}
    rest = [_rounded(p) for p in _fit_spline(segments, closed)]
    if closed and filled:
        return {"kind": "region", "curve": "spline", "rest": rest}
    return {"kind": "spline", "rest": rest, **({"closed": True} if closed else {})}


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The z component of 2D cross products (``a`` and ``b`` broadcast)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _rounded(p: np.ndarray) -> list[float]:
    return [round(float(p[0]), 4), round(float(p[1]), 4)]


def _bezier(segment: np.ndarray, t: np.ndarray) -> np.ndarray:
    t = t[:, None]
    u = 1 - t
    return (u ** 3 * segment[0] + 3 * u * u * t * segment[1] + 3 * u * t * t * segment[2]
            + t ** 3 * segment[3])


def _flatten(segments: list[np.ndarray]) -> list[np.ndarray]:
    """A polyline within :data:`TOLERANCE_PX` of the Bézier segments (by subdivision)."""
    points = [segments[0][0]]

    def split(seg: np.ndarray, depth: int) -> None:
        chord = seg[3] - seg[0]
        length = float(np.hypot(*chord))
        if length > 0:
            dist = max(abs(float(_cross(chord, seg[k] - seg[0]))) / length for k in (1, 2))
        else:
            dist = float(max(np.hypot(*(seg[k] - seg[0])) for k in (1, 2)))
        # A cubic stays within 3/4 of its handles' distance from the chord.
        if dist * 0.75 <= TOLERANCE_PX or depth > 16:
            points.append(seg[3])
            return
        a01, a12, a23 = (seg[0] + seg[1]) / 2, (seg[1] + seg[2]) / 2, (seg[2] + seg[3]) / 2
        b0, b1 = (a01 + a12) / 2, (a12 + a23) / 2
        mid = (b0 + b1) / 2
        split(np.array([seg[0], a01, b0, mid]), depth + 1)
        split(np.array([mid, b1, a23, seg[3]]), depth + 1)

    for seg in segments:
        split(seg, 0)
    return points


def _catmull_rom(points: np.ndarray, closed: bool, samples: int) -> list[np.ndarray]:
    """Each span of the engine's centripetal Catmull-Rom curve (the core's
    ``Curve::spline``: reflected end neighbours), sampled at ``samples`` parameters."""
    n = len(points)

    def at(i: int) -> np.ndarray:
        if closed:
            return points[i % n]
        if i < 0:
            return 2 * points[0] - points[min(1, n - 1)]
        if i >= n:
            return 2 * points[n - 1] - points[max(n - 2, 0)]
        return points[i]

    u = np.linspace(0.0, 1.0, samples)[:, None]
    h00, h10, h11, h01 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, u**3 - u**2, -2 * u**3 + 3 * u**2
    spans = []
    for i in range(n if closed else n - 1):
        a, b, c, d = at(i - 1), at(i), at(i + 1), at(i + 2)
        d0, d1, d2 = (float(np.hypot(*(y - x))) ** 0.5 for x, y in ((a, b), (b, c), (c, d)))
        chord = c - b
        t0 = np.zeros(2) if d1 == 0 or d0 == 0 else chord + d1 * ((b - a) / d0 - (c - a) / (d0 + d1))
        t1 = np.zeros(2) if d1 == 0 or d2 == 0 else chord + d1 * ((d - c) / d2 - (d - b) / (d1 + d2))
        spans.append(h00 * b + h10 * t0 + h11 * t1 + h01 * c)
    return spans


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Each point's distance to the polyline ``line`` (K, 2)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    denom = np.maximum((ab * ab).sum(1), 1e-300)
    ap = points[:, None, :] - a[None]
    t = np.clip((ap * ab[None]).sum(2) / denom[None], 0.0, 1.0)
    nearest = a[None] + t[..., None] * ab[None]
    return np.sqrt(((points[:, None, :] - nearest) ** 2).sum(2)).min(1)


def _fit_spline(segments: list[np.ndarray], closed: bool) -> list[np.ndarray]:
    """Control points of a centripetal Catmull-Rom spline through points of the Bézier
    path, within :data:`TOLERANCE_PX` of it both ways: the segments' end points, with more
    points of the path added in every span that strays further, until none does."""
    count = len(segments)

    def path_at(s: np.ndarray) -> np.ndarray:
        k = np.minimum(np.floor(s).astype(int), count - 1)
        out = np.empty((len(s), 2))
        for j in np.unique(k):
            mask = k == j
            out[mask] = _bezier(segments[j], s[mask] - j)
        return out

    params = list(np.arange(count + (0 if closed else 1), dtype=np.float64))
    for _ in range(24):
        controls = path_at(np.array(params))
        spans = _catmull_rom(controls, closed, 33)
        ends = params[1:] + ([float(count)] if closed else [])
        worse: list[int] = []
        for i, span in enumerate(spans):
            truth = path_at(np.linspace(params[i], ends[i], 65))
            error = max(_distance_to_polyline(span, truth).max(),
                        _distance_to_polyline(truth, span).max())
            if error > TOLERANCE_PX * 0.9:  # a margin for the polylines' own error
                worse.append(i)
        if not worse:
            return list(controls)
        for i in reversed(worse):
            params.insert(i + 1, (params[i] + ends[i]) / 2)
    return list(path_at(np.array(params)))
