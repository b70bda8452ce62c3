"""A process that forks after using pcdcodec: the child neither crashes nor hangs when it
collects what it inherited (writers, readers, their FFmpeg streams and threads), leaves the
parent's files alone, and reads and writes recordings of its own.

Each case runs in a fresh interpreter (tests/test_fork.py's SCRIPT), which forks and waits for
its child with a deadline, so a hang fails the test instead of stopping the run."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from .conftest import REPO

pytest.importorskip("av")

SCRIPT = textwrap.dedent(
    """
    import gc, os, signal, sys, time
    import numpy as np
    import pcdcodec
    from pcdcodec.recording.rig import CameraSpec, RigWriter

    case, where = sys.argv[1], sys.argv[2]
    W, H = 64, 48
    CAMERA = pcdcodec.CameraIntrinsics(W, H, 52.5, 52.5, 31.5, 23.5)

    def frames(n=3):
        yy, xx = np.mgrid[0:H, 0:W]
        for i in range(n):
            color = np.stack(
                [(xx * 4 + i * 9) % 256, (yy * 5 + i * 7) % 256, ((xx + yy) * 3 + i) % 256], -1
            ).astype(np.uint8)
            depth = (1000 + xx * 7 + yy * 11 + i * 13).astype(np.uint16)
            yield color, depth, 1_000_000_000 + i * 33_333_333

    def write(path, color):
        kw = {} if color is None else {"color": color}
        with pcdcodec.open(path, "w", intrinsics=CAMERA, depth_scale=1000.0, **kw) as w:
            for c, d, ts in frames():
                w.write(c, d, ts)

    def check(path):
        with pcdcodec.open(path) as rec:
            assert rec.verify().ok
            for f, (c, d, ts) in zip(rec, frames(), strict=True):
                assert f.timestamp_ns == ts and np.array_equal(f.depth, d)

    def use():
        # Used inside a function, as a program would: what is left are cycles, not yet freed.
        if case in ("h264", "ffv1"):
            write(f"{where}/parent.pcdc", case)
            return None
        if case == "rig":
            specs = [CameraSpec("a", CAMERA, 1000.0), CameraSpec("b", CAMERA, 1000.0)]
            with RigWriter(f"{where}/parent.pcdc", specs) as w:
                for c, d, ts in frames():
                    w.write("a", c, d, ts)
                    w.write("b", c, d, ts + 1000)
            return None
        write(f"{where}/parent.pcdc", None)
        threads = 4 if case == "reader-threads" else None
        rec = pcdcodec.open(f"{where}/parent.pcdc", threads=threads)
        assert len([f.color for f in rec]) == 3
        if case == "open-writer":  # a writer still open when the process forks
            w = pcdcodec.open(f"{where}/open.pcdc", "w", intrinsics=CAMERA, depth_scale=1000.0)
            for c, d, ts in frames(2):
                w.write(c, d, ts)
            return w
        return None

    open_writer = use()
    pid = os.fork()
    if pid == 0:
        gc.collect()
        if open_writer is not None:
            try:
                open_writer.write(*next(frames()))
                raise SystemExit("an inherited writer took a frame in the child")
            except pcdcodec.InputError as exc:
                assert "forked" in str(exc), exc
            open_writer.close()  # leaves the parent's file and threads alone
            del open_writer
            gc.collect()
        write(f"{where}/child.pcdc", None)
        check(f"{where}/child.pcdc")
        sys.exit(0)  # a normal exit: the interpreter's shutdown frees what is left
    deadline = time.monotonic() + 120
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            print("CHILD HUNG")
            sys.exit(3)
        time.sleep(0.05)
    print("child", status)
    if open_writer is not None:
        for c, d, ts in list(frames(3))[2:]:
            open_writer.write(c, d, ts)
        open_writer.close()
        with pcdcodec.open(f"{where}/open.pcdc") as rec:
            assert rec.verify().ok and len(rec) == 3
    sys.exit(0 if os.waitstatus_to_exitcode(status) == 0 else 4)
    """
)


@pytest.mark.parametrize("case", ["h264", "ffv1", "rig", "reader", "reader-threads", "open-writer"])
def test_a_forked_child_collects_what_it_inherited_and_records_its_own(
    case: str, tmp_path: Path
) -> None:
    script = tmp_path / "fork_case.py"
    script.write_text(SCRIPT)
    out = subprocess.run(
        [sys.executable, str(script), case, str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=400,
        cwd=REPO,
        env={**__import__("os").environ, "PYTHONPATH": str(REPO)},
        check=False,
    )
    assert out.returncode == 0, (out.stdout, out.stderr)
    assert "child 0" in out.stdout
    assert (tmp_path / "child.pcdc").exists()
