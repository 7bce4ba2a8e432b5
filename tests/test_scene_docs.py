"""The scene-format reference and the JSON Schema agree: the key tables in
docs/reference/scene-format.md are generated from the schema, and this test fails when they
are stale. Regenerate them with ``python tests/test_scene_docs.py``."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import jsonschema
import pytest

import inkwarp

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "reference" / "scene-format.md"
BEGIN, END = "<!-- BEGIN GENERATED FROM THE SCHEMA -->", "<!-- END GENERATED FROM THE SCHEMA -->"

OBJECTS = [  # (schema definition, heading)
    (None, "Scene (the top level)"),
    ("SolverDoc", "solver"),
    ("BeierNeelyDoc", "solver.beier_neely"),
    ("TpsExactDoc", "solver.tps_exact"),
    ("SolverOverrides", "layers[].solver"),
    ("LayerDoc", "layers[]"),
    ("FeatureDoc", "features[]"),
    ("KeyDoc", "features[].keys[]"),
]
ENUMS = ["FeatureKind", "Interpolation", "Curve", "Border", "Method", "Scheme"]


def _anchor(heading: str) -> str:
    return "".join(c for c in heading.lower().replace(" ", "-") if c.isalnum() or c == "-")


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else str(x)


def _type(schema: dict, defs: dict, plural: bool = False) -> str:
    s = "s" if plural else ""
    if "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[1]
        if name in ENUMS:
            return f"[{name}](#{name.lower()}){' names' if plural else ''}"
        heading = dict((d, h) for d, h in OBJECTS)[name]
        return f"[{heading}](#{_anchor(heading)}) object{s}"
    if "anyOf" in schema:
        return " or ".join(_type(a, defs, plural) for a in schema["anyOf"] if a.get("type") != "null")
    kind = schema.get("type")
    if isinstance(kind, list):
        kind = [k for k in kind if k != "null"][0]
    if kind == "array":
        items = schema.get("items", {})
        if items.get("type") == "array" and items.get("minItems") == 2:
            return "list of [x, y]"
        count = schema.get("minItems") if schema.get("minItems") == schema.get("maxItems") else None
        return f"list of {count or ''}{' ' if count else ''}{_type(items, defs, plural=True)}"
    if kind == "integer":
        low, high = schema.get("minimum"), schema.get("maximum")
        if low is not None and high is not None:
            return f"integer{s} {_number(low)}–{_number(high)}"
        return f"integer{s}" if low in (None, 0) else f"integer{s} ≥ {_number(low)}"
    if kind == "number":
        low = schema.get("minimum")
        return f"number{s}" if low is None else f"number{s} ≥ {_number(low)}"
    if kind == "boolean":
        return "true or false"
    return f"{kind or 'value'}{s}"


def render_tables(schema: dict) -> str:
    """The generated part of the reference: a table per object, a list per enumeration."""
    defs = schema["$defs"]
    out = []
    for name, heading in OBJECTS:
        definition = schema if name is None else defs[name]
        out.append(f"### {heading}\n")
        out.append(definition["description"].replace("\n", " ") + "\n")
        out.append("| key | type | required / default | meaning |")
        out.append("|---|---|---|---|")
        required = set(definition.get("required", []))
        for key, prop in definition["properties"].items():
            if key in required:
                default = "**required**"
            elif "default" in prop:
                default = f"`{json.dumps(prop['default'])}`"
            else:
                default = "optional"
            text = prop.get("description", "").replace("\n", " ").replace("|", "\\|")
            out.append(f"| `{key}` | {_type(prop, defs)} | {default} | {text} |")
        out.append("")
    for name in ENUMS:
        definition = defs[name]
        out.append(f"### {name}\n")
        out.append(definition["description"].replace("\n", " ") + "\n")
        for option in definition["oneOf"]:
            out.append(f"- `\"{option['const']}\"`: {option['description'].replace(chr(10), ' ')}")
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _generated_block(text: str) -> str:
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[start:end].strip("\n") + "\n"


def test_the_reference_tables_are_generated_from_the_current_schema():
    expected = render_tables(inkwarp.scene_schema())
    assert _generated_block(DOC.read_text(encoding="utf-8")) == expected, (
        "docs/reference/scene-format.md is stale: run `python tests/test_scene_docs.py`"
    )


def test_every_key_of_the_schema_is_in_the_reference():
    text = DOC.read_text(encoding="utf-8")
    schema = inkwarp.scene_schema()
    for definition in [schema, *schema["$defs"].values()]:
        for key in definition.get("properties", {}):
            assert f"`{key}`" in text


def _json_blocks(text: str):
    blocks, inside, lines = [], False, []
    for line in text.splitlines():
        if line.strip() == "```json":
            inside, lines = True, []
        elif inside and line.strip() == "```":
            inside = False
            blocks.append("\n".join(lines))
        elif inside:
            lines.append(line)
    return blocks


def test_the_reference_examples_are_valid_scenes():
    validator = jsonschema.Draft202012Validator(inkwarp.scene_schema())
    blocks = _json_blocks(DOC.read_text(encoding="utf-8"))
    assert blocks
    for block in blocks:
        scene = json.loads(block)
        validator.validate(scene)
        # The pictures named in the examples are not here: that must be their only problem.
        for path, message in inkwarp.validate_scene(scene):
            assert re.fullmatch(r"layers\[\d+\]\.(image|alpha|continuity)", path), (path, message)
            assert "no such file" in message


@pytest.mark.parametrize("example", sorted(ROOT.glob("examples/*/*.json")), ids=lambda p: p.parent.name + "/" + p.name)
def test_the_schema_accepts_the_examples(example):
    scene = json.loads(example.read_text(encoding="utf-8"))
    if not isinstance(scene, dict) or "inkwarp" not in scene:
        pytest.skip("not a scene")
    jsonschema.Draft202012Validator(inkwarp.scene_schema()).validate(scene)
    assert inkwarp.validate_scene(example) == []


if __name__ == "__main__":
    text = DOC.read_text(encoding="utf-8")
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    DOC.write_text(text[:start] + "\n" + render_tables(inkwarp.scene_schema()) + "\n" + text[end:], encoding="utf-8")
    print(f"updated {DOC}", file=sys.stderr)
