"""A property-based scene fuzzer: scenes built from awkward numbers and shapes either load
(and then render: validate passing means render does not fail on input) or give a
SceneError with a JSON path; nothing else escapes. A fixed, derandomized budget keeps it
to a few seconds in `make test`."""

from __future__ import annotations

import json
import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import inkwarp

AWKWARD = st.one_of(
    st.floats(-50, 80),
    st.sampled_from([0.0, -0.0, 1e-300, 1e6, -1e6, 1e6 + 1, 1e8, 1e300, 2.0 ** 64, -1e308]),
    st.integers(-3, 70),
)
FEATURE_KINDS = ["point", "polyline", "spline", "region", "cut"]


@st.composite
def scenes(draw):
    kind = draw(st.sampled_from(FEATURE_KINDS))
    n = 1 if kind == "point" else draw(st.integers(2 if kind != "region" else 3, 5))
    point = st.lists(AWKWARD, min_size=2, max_size=2)
    rest = draw(st.lists(point, min_size=n, max_size=n))
    times = draw(st.lists(st.one_of(st.floats(-1, 3), st.sampled_from([1e-300, 1e5, 1e6, 1e308])),
                          min_size=0, max_size=3))
    keys = [{"t": t, "points": draw(st.lists(point, min_size=n, max_size=n))} for t in times]
    feature = {"id": "f", "kind": kind, "rest": rest, "keys": keys}
    doc = {
        "inkwarp": 1,
        "width": draw(st.one_of(st.integers(1, 24), st.sampled_from([0, 40000, 100000]))),
        "height": draw(st.integers(1, 24)),
        "fps": draw(st.one_of(st.sampled_from([24, 0.5, 1e4]), st.floats(0.1, 60))),
        "layers": [{"name": "m", "offset": draw(st.lists(AWKWARD, min_size=2, max_size=2))}],
        "features": [feature],
        "solver": {
            "method": draw(st.sampled_from(["tps", "tps-exact", "triangulation", "beier-neely"])),
            "tension": draw(st.sampled_from([0.0, 0.5, 1e300, 1e7])),
            "beier_neely": {"b": draw(st.sampled_from([2.0, 1e308, 0.0]))},
        },
    }
    if draw(st.booleans()):
        doc["duration"] = draw(st.sampled_from([1.0, 1e308, 1e5, 0.01]))
    return doc


@settings(max_examples=60, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
def test_scenes_validate_and_render_or_say_where(doc) -> None:
    problems = inkwarp.validate_scene(doc)
    try:
        scene = inkwarp.Scene.from_dict(doc)
    except inkwarp.SceneError as err:
        assert problems, f"Scene refused what validate passed: {err}"
        assert all(isinstance(p, str) and isinstance(m, str) and m for p, m in err.problems)
        return
    assert not problems, problems
    assert 1 <= scene.frame_count <= 10 ** 8 and math.isfinite(scene.duration)
    frame = scene.render(frame=scene.frame_count // 2)
    assert frame.shape == (scene.height, scene.width, 4) and frame.dtype == np.uint8
    json.dumps(scene.to_dict())
