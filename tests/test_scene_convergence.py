"""A solve that stops before it converges is not silent: ``Scene.render``, ``field`` and
``frames`` warn with ``inkwarp.ConvergenceWarning`` naming the layer and the frame, and
``inkwarp render`` prints one line on stderr (not a traceback)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from scene_art import gradient, two_layer_scene, write_scene

import inkwarp
from inkwarp.cli import main


def _stopped_early() -> dict:
    data = two_layer_scene()
    # One cycle at a tolerance it cannot reach: the front layer's solve stops unconverged.
    data["layers"][1]["solver"] = {"max_cycles": 1, "tolerance": 1e-9}
    return data


def test_render_field_and_frames_warn_with_layer_and_frame(tmp_path):
    scene = inkwarp.Scene.load(write_scene(tmp_path, _stopped_early()))
    with pytest.warns(inkwarp.ConvergenceWarning, match=r'layer "front" at t = 1 s \(frame 20\): .*did not converge \(1 cycle, '):
        frame = scene.render(time=1.0)
    assert frame.shape == (30, 40, 4)
    with pytest.warns(inkwarp.ConvergenceWarning, match=r'layer "front" at t = 0.5 s \(frame 10\)'):
        field = scene.field(time=0.5, layer="front")
    assert np.isfinite(field).all()
    with pytest.warns(inkwarp.ConvergenceWarning) as caught:
        frames = list(scene.frames(3, 6, threads=2))
    assert len(frames) == 3 and frames[0].shape == (30, 40, 4)
    messages = [str(w.message) for w in caught if issubclass(w.category, inkwarp.ConvergenceWarning)]
    assert any("(frame 4)" in m for m in messages) and all('layer "front"' in m for m in messages)
    # Each at the caller's line, inkwarp.render's too (it named the loop in rendering.py).
    with pytest.warns(inkwarp.ConvergenceWarning) as caught:
        inkwarp.render(scene, tmp_path / "frames/", frames=(3, 5), progress=False)
    assert {w.filename for w in caught} == {__file__}, {(w.filename, w.lineno) for w in caught}


def test_a_converged_scene_does_not_warn(tmp_path):
    scene = inkwarp.Scene.load(write_scene(tmp_path))
    # pytest turns every warning into an error: these would fail if one were issued.
    scene.render(time=1.0)
    scene.field(time=0.5, layer=1)
    assert len(list(scene.frames(0, 3))) == 3


def test_the_cli_prints_one_line_and_succeeds(tmp_path, capsys):
    path = write_scene(tmp_path, _stopped_early())
    assert main(["render", str(path), "-o", str(tmp_path / "f.png"), "--frame", "20", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith('inkwarp render: warning: layer "front" at t = 1 s (frame 20)')
    assert (tmp_path / "f.png").exists()
    assert main(["render", str(path), "-o", str(tmp_path / "frames") + "/", "--frames", "0:4", "--quiet"]) == 0
    lines = capsys.readouterr().err.splitlines()
    # Frame 0 is at rest (nothing to solve); frames 1-3 stop early: the first is shown,
    # the others counted.
    assert len(lines) == 2
    assert lines[0].startswith('inkwarp render: warning: layer "front" at t = 0.05 s (frame 1)')
    assert lines[1] == "inkwarp render: warning: 2 more solves did not converge (frames 2, 3)"
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [f"frame_{i:04d}.png" for i in range(4)]
    json.loads(path.read_text())


def test_strict_exits_3_when_a_solve_did_not_converge_and_0_when_all_did(tmp_path, capsys):
    # A farm reads the exit status, not stderr: --strict says 3, with the output written.
    path = write_scene(tmp_path, _stopped_early())
    assert main(["render", str(path), "-o", str(tmp_path / "f.png"), "--frame", "20", "-q", "--strict"]) == 3
    assert (tmp_path / "f.png").exists() and "did not converge" in capsys.readouterr().err
    assert main(["field", str(path), "-o", str(tmp_path / "f.npy"), "--frame", "20", "--layer", "front", "-q", "--strict"]) == 3
    assert (tmp_path / "f.npy").exists()
    (tmp_path / "good").mkdir()
    good = write_scene(tmp_path / "good", two_layer_scene())
    assert main(["render", str(good), "-o", str(tmp_path / "g.png"), "--frame", "20", "-q", "--strict"]) == 0


def test_inkwarp_field_prints_the_same_one_line(tmp_path, capsys):
    path = write_scene(tmp_path, _stopped_early())
    assert main(["field", str(path), "-o", str(tmp_path / "f.npy"), "--frame", "20", "--layer", "front", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ConvergenceWarning" not in err and "Traceback" not in err
    assert err.startswith('inkwarp field: warning: layer "front" at t = 1 s (frame 20)')
    # The layer's small torn piece is solved exactly in its one cycle: what stops it is a
    # tolerance finer than the field's float32 precision, and the advice says so.
    assert "finer than the field's precision at these displacements; use a coarser solver.tolerance" in err and "max_cycles" not in err


def test_a_solve_that_runs_out_of_cycles_says_raise_max_cycles(tmp_path):
    # A layer large enough to be iterated (not solved whole), stopped after 2 cycles at a
    # reachable tolerance: the report's reason is its cycle cap, and so is the advice.
    scene = larger_front(tmp_path, {"max_cycles": 2, "tolerance": 0.001})
    with pytest.warns(inkwarp.ConvergenceWarning) as caught:
        scene.field(time=1.0, layer="front")
    message = str(caught[0].message)
    # The setting in effect is the layer's own: the advice names it, with its value.
    assert "(2 cycles" in message and "raise layers[1].solver.max_cycles (the layer's own, 2)" in message, message
    # The accuracy it may miss is the contract of the layer's own tolerance: 5 times 0.001.
    assert "off by more than 0.005 px (5 times solver.tolerance)" in message, message


def larger_front(tmp_path, solver: dict) -> inkwarp.Scene:
    """`two_layer_scene` at 160 x 120 (a front layer iterated, not solved whole) with the
    front layer's `solver`."""
    data = two_layer_scene()
    data["width"], data["height"] = 160, 120
    data["layers"][1]["solver"] = solver
    path = write_scene(tmp_path, data)
    Image.fromarray(gradient(160, 120, hole=(slice(40, 80), slice(60, 100)))).save(tmp_path / "front.png")
    Image.fromarray(gradient(160, 120)).save(tmp_path / "back.png")
    return inkwarp.Scene.load(path)


def test_a_southwell_warning_does_not_point_at_max_cycles(tmp_path):
    scene = larger_front(tmp_path, {"scheme": "southwell", "tolerance": 0.001})
    with pytest.warns(inkwarp.ConvergenceWarning) as caught:
        scene.field(time=1.0, layer="front")
    message = str(caught[0].message)
    assert "fixed budget" in message and "multigrid scheme" in message and "max_cycles" not in message
