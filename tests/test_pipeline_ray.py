"""Renders on a real local Ray cluster (two CPUs): chunks gathered in order equal a
sequential render; an address where no cluster answers is a clear error."""

from __future__ import annotations

import socket
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import inkwarp
from _cli_scenes import leftovers, write_scene
from inkwarp.cli import main
from test_pipeline_outputs import decode_rgba, png_frames, run, wavy_doc

ray = pytest.importorskip("ray", reason="make test installs ray (inkwarp[ray])")


def free_port() -> int:
    """A port of 127.0.0.1 that was free a moment ago."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def quiet_local_render(scene: Path, out: Path) -> int:
    """`inkwarp render SCENE -o OUT --frames 0:2 --ray -q` on a cluster it starts; its exit status."""
    assert not ray.is_initialized()
    try:
        code = main(["render", str(scene), "-o", str(out), "--frames", "0:2", "--ray", "-q"])
        # Left before the command returns, not at the interpreter's exit (where a Ctrl-C in
        # Ray's own shutdown printed a traceback and left the local cluster's agents running).
        assert not ray.is_initialized()
        return code
    finally:
        ray.shutdown()


def test_an_address_nobody_answers_at_is_a_clear_error(capsys, tmp_path):
    scene = write_scene(tmp_path / "s")
    port = free_port()
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.gif", "--ray",
                       f"127.0.0.1:{port}")
    assert code == 2 and f"--ray 127.0.0.1:{port}: no Ray cluster answers there" in err
    assert "Traceback" not in err and not (tmp_path / "a.gif").exists()
    assert leftovers(tmp_path) == []
    # In Python the message names the argument, not the command line's option.
    with pytest.raises(ValueError, match=rf"^ray='127\.0\.0\.1:{port}': no Ray cluster answers there"):
        inkwarp.render(inkwarp.Scene.load(scene), tmp_path / "a.gif", ray=f"127.0.0.1:{port}", progress=False)
    assert not (tmp_path / "a.gif").exists() and leftovers(tmp_path) == []
    # A port out of range is named as such (it read "Connection refused", or an overflow).
    for bad in ("99999", "0"):
        code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.gif", "--ray", f"127.0.0.1:{bad}")
        assert code == 2 and f"--ray 127.0.0.1:{bad}: {bad} is not a port (ports run from 1 to 65535)" in err, err


def test_an_address_where_something_else_answers_is_a_clear_error(capsys, tmp_path):
    # A web server on a mistyped port: Ray retried without end, printing its own warnings.
    import threading
    from http.server import HTTPServer, SimpleHTTPRequestHandler

    from inkwarp.rendering import _check_address

    server = HTTPServer(("127.0.0.1", 0), SimpleHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        port = server.server_address[1]
        scene = write_scene(tmp_path / "s")
        code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.gif", "--ray", f"127.0.0.1:{port}")
        assert code == 2 and f"--ray 127.0.0.1:{port}: something answers there, but not a Ray cluster" in err, err
        assert not (tmp_path / "a.gif").exists() and leftovers(tmp_path) == []
    finally:
        server.shutdown()
        server.server_close()
    # A Ray head's own address passes the check.
    ray.init(address="local", num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        _check_address(ray.get_runtime_context().gcs_address)
    finally:
        ray.shutdown()


def test_ray_chunks_gathered_in_order_equal_a_sequential_render(capsys, tmp_path):
    scene_path = write_scene(tmp_path / "s", wavy_doc())
    code, _, err = run(capsys, "render", scene_path, "-o", tmp_path / "seq/", "-q")
    assert code == 0, err
    sequential = png_frames(tmp_path / "seq", 40)
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        # Frames 5 to 39 in two chunks (5:16 with its pre-roll, 16:40), gathered in order.
        code, stdout, err = run(capsys, "render", scene_path, "-o", tmp_path / "ray/",
                                "--frames", "5:40", "--ray")
        assert code == 0, err
        assert "on Ray" in stdout and "render on Ray (2 chunks)" in err
        for got, want in zip(png_frames(tmp_path / "ray", 35, first=5), sequential[5:]):
            assert np.abs(got.astype(int) - want).max() <= 1
        # The Python API, into a single-file format.
        scene = inkwarp.Scene.load(scene_path)
        paths = inkwarp.render(scene, tmp_path / "anim.apng", ray=True)
        frames = decode_rgba(paths[0], scene.width, scene.height)
        assert len(frames) == 40
        for got, want in zip(frames, sequential):
            assert np.abs(got.astype(int) - want).max() <= 1
    finally:
        ray.shutdown()
    assert leftovers(tmp_path) == []


def test_a_cluster_short_of_memory_renders_on_fewer_workers(capsys, tmp_path):
    """Each worker asks Ray for the scene's memory: a cluster with two CPUs but memory for
    one worker renders on one worker at a time, the same frames. Frames 8 to 39 make two
    chunks (8:32 starts inside a warm-start chain): the second starts when the first ends."""
    scene_path = write_scene(tmp_path / "s", wavy_doc())
    scene = inkwarp.Scene.load(scene_path)
    sequential = inkwarp.render(scene, tmp_path / "seq/")
    ray.init(address="local", num_cpus=2, _memory=int(1.5 * scene.render_bytes), include_dashboard=False,
             log_to_driver=False)
    try:
        assert inkwarp.rendering.ray_workers(ray.nodes(), scene.render_bytes) == 1
        code, _, err = run(capsys, "render", scene_path, "-o", tmp_path / "ray/", "--ray",
                           "--frames", "8:40")
        assert code == 0, err
        assert "render on Ray (2 chunks)" in err
        want = [np.asarray(Image.open(p).convert("RGBA")) for p in sequential[8:]]
        assert len(want) == 32
        for got, w in zip(png_frames(tmp_path / "ray", len(want), first=8), want):
            assert np.abs(got.astype(int) - w).max() <= 1
    finally:
        ray.shutdown()
    assert leftovers(tmp_path) == []


def test_a_chunk_whose_worker_dies_is_rendered_again_on_a_new_one(capsys, tmp_path, monkeypatch):
    """A worker killed mid-render (for memory, or its node lost): its chunk's frames not yet
    received are rendered on a new actor, the same frames; it was a traceback calling itself
    an inkwarp bug."""
    import os
    import signal
    import subprocess

    def ours(pid: int) -> bool:
        while pid > 1:
            try:
                pid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
            except OSError:
                return False
            if pid == os.getpid():
                return True
        return False

    scene_path = write_scene(tmp_path / "s", wavy_doc())
    scene = inkwarp.Scene.load(scene_path)
    sequential = [np.asarray(Image.open(p).convert("RGBA")) for p in inkwarp.render(scene, tmp_path / "seq/")]
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        def render_killing_one() -> list[np.ndarray]:
            frames: list[np.ndarray] = []
            for frame in inkwarp.rendering._ray_frames(scene, 0, 40, method=None, address=True, progress=False):
                frames.append(frame)
                if len(frames) == 1:  # this cluster's actors (started below this process), rendering
                    pids = [pid for pid in subprocess.run(["pgrep", "-f", "ray::_ChunkRenderer"], capture_output=True,
                                                          text=True).stdout.split() if ours(int(pid))]
                    assert pids, "no Ray actor process to kill"
                    for pid in pids:
                        os.kill(int(pid), signal.SIGKILL)
            return frames

        capsys.readouterr()
        with pytest.warns(inkwarp.errors.InkwarpWarning, match=r"the Ray worker rendering frames \d+:\d+ died \(.*\); rendering them on a new one"):
            frames = render_killing_one()
        assert len(frames) == 40
        for got, want in zip(frames, sequential):
            assert np.abs(got.astype(int) - want).max() <= 1
        # Ray's own notice of the death ("(raylet) A worker died or was killed ...", in colour)
        # came on stdout, which holds the command line's summary line only: now on stderr.
        import time

        out, err = capsys.readouterr()
        deadline = time.monotonic() + 10
        while "worker died" not in (out + err).lower() and time.monotonic() < deadline:
            time.sleep(0.2)
            more = capsys.readouterr()
            out, err = out + more.out, err + more.err
        assert "(raylet)" not in out and "worker died" not in out.lower(), out
        if "worker died" in err.lower():  # (it came within the wait: Ray gives it a moment after)
            assert "(raylet) A worker died or was killed" in err and "\x1b[" not in err, err
        # With no restarts allowed the death is said in one line, with the fix.
        monkeypatch.setattr(inkwarp.rendering, "RAY_RESTARTS", 0)
        with pytest.raises(inkwarp.errors.WorkerLostError, match=r"the Ray worker rendering frames \d+:\d+ died 1 time \(\w+: .*run again to resume"):
            render_killing_one()
    finally:
        ray.shutdown()


def test_rays_notices_to_the_driver_go_to_stderr_plain_and_its_other_output_as_before(capsys):
    # Ray's driver printed its nodes' notices ("(raylet) A worker died or was killed ...")
    # on stdout in colour, though the command line keeps stdout for its summary line.
    from ray._private import worker

    inkwarp.rendering._ray_notices_to_stderr()
    inkwarp.rendering._ray_notices_to_stderr()  # once only: not wrapped twice
    notice = "A worker died or was killed while executing a task by an unexpected system error. \x1b[33mcheck\x1b[0m"
    worker.print_to_stdstream({"lines": [notice], "pid": "raylet", "is_err": False}, ignore_prefix=False)
    out, err = capsys.readouterr()
    assert out == "" and err == "(raylet) A worker died or was killed while executing a task by an unexpected system error. check\n"
    # A task's own printing (with log_to_driver) still goes where Ray sends it.
    worker.print_to_stdstream({"lines": ["hello from a task 7f3a"], "pid": 4242, "is_err": False,
                               "ip": "127.0.0.1", "localhost": "127.0.0.1"}, ignore_prefix=False)
    out, err = capsys.readouterr()
    assert "hello from a task 7f3a" in out and err == ""


def test_the_workers_convergence_warnings_are_said_here_and_strict_holds(capsys, tmp_path):
    # On Ray the solves that stopped early were said in the workers' logs only, and --strict
    # was refused; now the warnings come back with the frames, as a local render says them.
    import scene_art
    from test_scene_convergence import _stopped_early

    (tmp_path / "s").mkdir()
    scene = scene_art.write_scene(tmp_path / "s", _stopped_early())
    code, _, local = run(capsys, "render", scene, "-o", tmp_path / "here/", "--frames", "0:6", "-q")
    assert code == 0 and "did not converge" in local
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        code, _, err = run(capsys, "render", scene, "-o", tmp_path / "ray/", "--frames", "0:6", "--ray", "-q")
        assert code == 0 and err == local, err
        code, _, err = run(capsys, "render", scene, "-o", tmp_path / "strict/", "--frames", "0:6", "--ray", "-q", "--strict")
        assert code == 3 and err == local, err
    finally:
        ray.shutdown()


def test_a_quiet_render_on_a_cluster_it_starts_prints_nothing(capfd, monkeypatch, tmp_path):
    # Ray's own start-up lines (such as its token notice) went to the terminal under -q, and
    # its Python warnings to a `sys.stderr` that is not fd 2 (a notebook's, pytest's) even so.
    # Ray gives its token notice where RAY_AUTH_MODE is unset, which a cluster started earlier
    # in this process set.
    monkeypatch.delenv("RAY_AUTH_MODE", raising=False)
    code = quiet_local_render(write_scene(tmp_path / "s"), tmp_path / "a.gif")
    out, err = capfd.readouterr()
    assert code == 0 and out == "" and err == "", err
    assert (tmp_path / "a.gif").exists() and leftovers(tmp_path) == []


def test_a_cluster_ray_start_left_that_has_gone_is_passed_over(monkeypatch, tmp_path):
    # `ray start --head` writes its address to Ray's temporary folder; killed, it leaves the
    # file, and ray.init() without an address retried that address without end. --ray
    # without an address then starts a cluster of its own.
    import shutil
    import tempfile

    ray_tmp = Path(tempfile.mkdtemp(prefix="iw", dir="/tmp"))  # short: Ray's sockets live there
    try:
        port = free_port()
        (ray_tmp / "ray").mkdir()
        (ray_tmp / "ray" / "ray_current_cluster").write_text(f"127.0.0.1:{port}\n")
        monkeypatch.setenv("RAY_TMPDIR", str(ray_tmp))
        monkeypatch.delenv("RAY_ADDRESS", raising=False)
        code = quiet_local_render(write_scene(tmp_path / "s"), tmp_path / "a.gif")
        assert code == 0 and (tmp_path / "a.gif").exists() and leftovers(tmp_path) == []
    finally:
        shutil.rmtree(ray_tmp, ignore_errors=True)


def test_a_ray_address_in_the_environment_that_nobody_answers_at_is_a_clear_error(capsys, monkeypatch, tmp_path):
    # Ray joins RAY_ADDRESS when --ray gives none, and retried a dead one without end.
    port = free_port()
    monkeypatch.setenv("RAY_ADDRESS", f"127.0.0.1:{port}")
    scene = write_scene(tmp_path / "s")
    code, _, err = run(capsys, "render", scene, "-o", tmp_path / "a.gif", "--ray")
    assert code == 2 and f"RAY_ADDRESS=127.0.0.1:{port}, the cluster --ray without an address joins: no Ray cluster answers there" in err, err
    assert "unset RAY_ADDRESS to start a local one" in err and "Traceback" not in err
    assert not (tmp_path / "a.gif").exists() and leftovers(tmp_path) == []


def test_sigterm_mid_render_on_ray_ends_it_as_it_ends_a_local_render(tmp_path):
    # Joining Ray installed Ray's SIGTERM handlers (exit status 1, a crash dump), and the
    # signal's exception raised inside Ray's wait came out as a SystemError (an internal
    # error): a farm's scheduler cancelling the job could not tell it from a crash. (Not
    # SIGINT: a test run in the background, as a CI job may be, starts Python ignoring it.)
    import os
    import signal
    import subprocess
    import sys
    import time

    from _cli_scenes import square_doc

    doc = square_doc()
    doc["duration"] = 500.0  # 2000 frames: far more than the time it takes to stop it
    scene = write_scene(tmp_path / "s", doc)
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    process = subprocess.Popen([sys.executable, "-m", "inkwarp.cli", "render", str(scene), "-o", str(tmp_path / "a.mp4"),
                                "--ray", "-q"], stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 180
    while not leftovers(tmp_path) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)  # frames coming in
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 143 and stderr.strip().endswith("inkwarp render: terminated"), stderr
    assert sorted(os.listdir(tmp_path)) == ["s"]


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="the processes are found through /proc (Linux)")
def test_a_local_start_interrupted_stops_what_it_had_started(monkeypatch):
    # Ctrl-C while Ray was starting a local cluster (before it knew its processes) left its
    # dashboard and runtime-env agents running for a minute after inkwarp had exited.
    import subprocess
    import time

    from inkwarp import rendering

    started = []

    def interrupted_init(**_):
        # A process of the cluster with one of its own, as the raylet starts its agents.
        started.append(subprocess.Popen(["sh", "-c", "sleep 60 & wait"]))
        time.sleep(0.3)
        started.extend(rendering._descendants() - {started[0].pid})
        raise KeyboardInterrupt

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setattr(rendering, "_left_by_ray_start", lambda: None)
    monkeypatch.setattr(ray, "init", interrupted_init)
    assert not ray.is_initialized()
    with pytest.raises(KeyboardInterrupt):
        rendering._ray_join(ray, True, True, False)
    shell, *below = started
    assert shell.wait(timeout=10) is not None and below  # stopped, not left to run its minute
    for _ in range(100):  # (the shell's own child, reaped by init)
        if not any(Path(f"/proc/{pid}").exists() for pid in below):
            break
        time.sleep(0.05)
    assert not any(Path(f"/proc/{pid}").exists() for pid in below)
