"""``inkwarp schema``: the JSON Schema of scene files."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from inkwarp.cli import _common

EPILOG = """\
examples:
  inkwarp schema                       print it
  inkwarp schema -o scene.schema.json  write it to a file (for an editor's completion)

The schema is generated from the engine's own types: its keys, types and
kinds are the ones 'inkwarp validate' and 'inkwarp render' read. They check
more than a schema can say (fps from 0.001 to 1000, ids unique, keys in
time order, images that exist), so a scene the schema passes may still be
refused.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "schema", help="print the JSON Schema of scene files",
        description="Print the JSON Schema of inkwarp scene files (format version 1).",
        epilog=EPILOG, formatter_class=_common.formatter)
    parser.add_argument("-o", "--output", metavar="FILE",
                        help="write the schema to FILE instead of printing it")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import inkwarp

    text = json.dumps(inkwarp.scene_schema(), indent=2, sort_keys=False) + "\n"
    if args.output is None:
        print(text, end="")
        return 0
    target = Path(args.output)
    from inkwarp import outputs, video

    video.check_file(target, ".json")
    outputs.check_ours(target, lambda doc: str(doc.get("$id", "")).startswith("https://inkwarp.dev/"), "schema")
    video.write_bytes(target, text.encode("utf-8"))
    print(f"wrote {target}")
    return 0
