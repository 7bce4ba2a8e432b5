"""``inkwarp transfer``: map one scene's animation onto another drawing."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

EXAMPLE = """\
examples:
  inkwarp transfer --source examples/face/scene.json --target examples/transfer/cat-target.json -o cat.json

The target's features are matched to the source's by id (same kind, same number of
control points); its keys become the source's keys mapped through the thin-plate map
from the source's rest drawing to the target's. Target-only features keep their keys.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "transfer",
        help="transfer a scene's animation onto another drawing",
        description="Transfer the source scene's animation onto the target scene's drawing "
        "(the paper's cross-synthesis) and write the result as a new scene.",
        epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--source", required=True, metavar="A.json", help="the animated scene")
    parser.add_argument("--target", required=True, metavar="B.json", help="the scene that receives the motion")
    parser.add_argument("-o", "--output", required=True, metavar="C.json", help="where to write the result")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from inkwarp.cli._common import warnings_as_lines
    from inkwarp.transfer import transfer_dict

    out = Path(args.output)
    if out.suffix.lower() != ".json":
        raise ValueError(f"the output {out} must be a .json scene file.")
    from inkwarp.outputs import check_not_the_input
    from inkwarp.video import check_file

    check_file(out)
    for option, given in (("--source", args.source), ("--target", args.target)):
        check_not_the_input(out, given, option, "-transferred")
    with warnings_as_lines("transfer"):
        doc = transfer_dict(args.source, args.target, relative_to=out.resolve().parent)
    from inkwarp._atomic import write_text

    write_text(out, json.dumps(doc, indent=2) + "\n", suffix=".json")
    if not args.quiet:
        moved = sum(1 for f in doc.get("features", []) if f.get("keys"))
        print(f"wrote {out} ({moved} animated features)")
    return 0
