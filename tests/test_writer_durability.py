"""A frame handed to the writer reaches the file as soon as it is encoded, whatever follows."""

from __future__ import annotations

import contextlib
import os
import random
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

import pcdcodec
from pcdcodec.color.base import Packet, StreamCodec
from pcdcodec.datasets import RGBDSequence, load_sample
from pcdcodec.depth import Zstd

from .test_write_safety import _FailingZstd

STEP = 33_000_000  # ns between frames


@pytest.fixture(scope="module")
def sample() -> RGBDSequence:
    return load_sample(max_frames=12)


def _writer(path: Path, sample: RGBDSequence, **options: Any) -> pcdcodec.RecordingWriter:
    return pcdcodec.open(
        path, "w", intrinsics=sample.intrinsics, depth_scale=sample.depth_scale, **options
    )


def _poll(condition: Callable[[], bool], timeout: float = 5.0) -> bool:
    """Whether ``condition`` came true within ``timeout`` seconds (a generous bound, not a
    measurement)."""
    end = time.monotonic() + timeout
    while True:
        if condition():
            return True
        if time.monotonic() > end:
            return False
        time.sleep(0.01)


def _readable(path: Path) -> int:
    """Frames a separate reader finds in the (possibly unfinished) file."""
    with pcdcodec.open(path) as rec:
        return len(rec)


# -- frames are written without waiting for later ones ----------------------------------------


def _encoded_groups(sample: RGBDSequence, frames: int) -> list[list[Packet]]:
    codec = pcdcodec.get_codec("h264", kind="color")
    assert isinstance(codec, StreamCodec)
    encoder = codec.encoder(sample.intrinsics.width, sample.intrinsics.height, 30.0)
    groups = [encoder.encode(sample[i].color, i * STEP) for i in range(frames)]
    assert all(len(g) == 1 for g in groups)  # low delay: each frame's packet comes with it
    return groups


@pytest.mark.parametrize("how", ["write", "write_frames", "write_encoded"])
def test_a_separate_reader_sees_every_frame_handed_in_while_the_writer_is_open(
    tmp_path: Path, sample: RGBDSequence, how: str
) -> None:
    path = tmp_path / "open.pcdc"
    n = 6
    rec = _writer(path, sample)  # the default codecs, in_flight = 4
    try:
        if how == "write":
            for i in range(n):
                rec.write(sample[i].color, sample[i].depth, i * STEP)
        elif how == "write_frames":
            rec.write_frames((sample[i].color, sample[i].depth, i * STEP) for i in range(n))
        else:
            for i, group in enumerate(_encoded_groups(sample, n)):
                rec.write_encoded(group, sample[i].depth, i * STEP)
        # Nothing more is handed in: the frames still reach the file, without close().
        assert _poll(lambda: _readable(path) == n), f"{_readable(path)} of {n} frames readable"
        assert rec.frames_complete == n
        with pcdcodec.open(path) as back:
            assert not back.indexed
            for i, frame in enumerate(back):
                assert frame.timestamp_ns == i * STEP
                np.testing.assert_array_equal(frame.depth, sample[i].depth)
                assert frame.color is not None
    finally:
        rec.close()
    with pcdcodec.open(path) as back:
        assert back.indexed
        assert len(back) == n
        assert back.verify().ok


def test_flush_waits_for_every_frame_handed_in(tmp_path: Path, sample: RGBDSequence) -> None:
    path = tmp_path / "f.pcdc"
    with _writer(path, sample) as rec:
        for i in range(5):
            rec.write(sample[i].color, sample[i].depth, i * STEP, pose=np.eye(4))
            rec.flush()
            assert rec.frames_complete == rec.frames_written == rec.poses_written == i + 1
            assert _readable(path) == i + 1
    with pcdcodec.open(path) as back:
        assert len(back) == 5
        assert back.has_poses


# -- the queue still bounds memory -------------------------------------------------------------


class _GatedZstd(Zstd):
    """zstd that waits for a gate before each frame, as a codec slower than the caller."""

    def __init__(self) -> None:
        super().__init__()
        self.gate = threading.Event()
        self.calls = 0

    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        return ("level",)  # the file records plain zstd, which reads it back

    def encode(self, depth: npt.ArrayLike) -> bytes:
        self.calls += 1
        assert self.gate.wait(30), "the test never opened the gate"
        return super().encode(depth)


def test_a_caller_faster_than_the_codecs_waits_on_the_bounded_queue(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "slow.pcdc"
    codec = _GatedZstd()
    rec = _writer(path, sample, depth=codec, in_flight=3)
    handed: list[int] = []

    def produce() -> None:
        for i in range(8):
            rec.write(sample[i].color, sample[i].depth, i * STEP)
            handed.append(i)

    thread = threading.Thread(target=produce)
    thread.start()
    try:
        # With no frame encoded, write() returns for in_flight frames and blocks on the next.
        assert _poll(lambda: len(handed) == 3)
        time.sleep(0.2)  # a write() that wrongly went on would show here
        assert handed == [0, 1, 2]
        assert rec.frames_written == 0
        assert codec.calls == 1  # the depth thread is on frame 0; 1 to 3 wait as copies
    finally:
        codec.gate.set()
        thread.join(30)
    assert not thread.is_alive()
    rec.close()
    with pcdcodec.open(path) as back:
        assert len(back) == 8
        for i, frame in enumerate(back):
            np.testing.assert_array_equal(frame.depth, sample[i].depth)


# -- errors met in the background are raised --------------------------------------------------


def test_a_background_encode_error_is_raised_by_a_later_write(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "e.pcdc"
    rec = _writer(path, sample, depth=_FailingZstd(fail_on=3), in_flight=4)
    for i in range(3):
        rec.write(sample[i].color, sample[i].depth, i * STEP)
    # Frame 2 fails on the depth thread. At most in_flight frames wait, so one of the next
    # writes finds the error, whenever the encode ran; it raises before taking its frame.
    handed = 3
    raised: RuntimeError | None = None
    for i in range(3, 3 + rec.in_flight + 2):
        try:
            rec.write(sample[i].color, sample[i].depth, i * STEP)
        except RuntimeError as exc:
            raised = exc
            break
        handed += 1
    assert raised is not None
    assert "call 3" in str(raised)
    if sys.version_info >= (3, 11):
        assert f"frame at {2 * STEP} ns" in "\n".join(getattr(raised, "__notes__", []))
    # The writer goes on, and the error is not raised again.
    rec.write(sample[11].color, sample[11].depth, 11 * STEP)
    rec.close()
    with pcdcodec.open(path) as back:
        kept = [int(t) // STEP for t in back.timestamps]
        assert kept == [i for i in range(handed) if i != 2] + [11]
        assert back.verify().ok


def test_a_background_error_is_raised_by_flush_and_close(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "e.pcdc"
    rec = _writer(path, sample, depth=_FailingZstd(fail_on=2))
    rec.write(sample[0].color, sample[0].depth, 0)
    rec.write(sample[1].color, sample[1].depth, STEP)
    with pytest.raises(RuntimeError, match="call 2"):
        rec.flush()
    rec.flush()  # raised once
    rec.close()
    rec = _writer(tmp_path / "c.pcdc", sample, depth=_FailingZstd(fail_on=2))
    rec.write(sample[0].color, sample[0].depth, 0)
    rec.write(sample[1].color, sample[1].depth, STEP)
    with pytest.raises(RuntimeError, match="call 2"):
        rec.close()
    with pcdcodec.open(tmp_path / "c.pcdc") as back:
        assert back.indexed
        assert [int(t) for t in back.timestamps] == [0]


def test_abort_stops_the_writing_thread_before_closing_the_file(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "a.pcdc"
    before = set(threading.enumerate())
    rec = _writer(path, sample)
    for i in range(6):
        rec.write(sample[i].color, sample[i].depth, i * STEP)
    rec.abort()
    assert set(threading.enumerate()) <= before  # no codec nor writer thread runs on
    written = rec.frames_written
    with pcdcodec.open(path) as back:
        assert len(back) == written <= 6


# -- a killed writer ---------------------------------------------------------------------------

# Records the sample cut to 160x120, so the default codecs keep up with 30 fps on a busy
# machine. Prints the number of each frame before handing it in; in "idle" mode, waits after
# the last frame until the writer has written everything, then prints "idle". Frames come at
# most ``fps`` a second.
KILLED_WRITER = textwrap.dedent(
    """
    import sys, time, pcdcodec
    path, mode, count, fps = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
    seq = pcdcodec.load_sample()
    i0 = seq.intrinsics
    cam = pcdcodec.CameraIntrinsics(160, 120, i0.fx / 4, i0.fy / 4, i0.cx / 4, i0.cy / 4)
    frames = [(f.color[::4, ::4].copy(), f.depth[::4, ::4].copy()) for f in seq]
    with pcdcodec.open(path, "w", intrinsics=cam, depth_scale=seq.depth_scale) as rec:
        for k in range(count):
            time.sleep(1 / fps)  # never a burst to catch up
            print(k, flush=True)
            color, depth = frames[k % len(frames)]
            rec.write(color, depth, k * 33_000_000)
        rec.flush()  # returns once every frame is written and flushed to the file
        print("idle", flush=True)
        time.sleep(60)
    """
)


def _kill_writer(
    path: Path, mode: str, count: int, after: float, *, fps: float = 30, from_first: bool = False
) -> tuple[int, int]:
    """Run the writer, kill it ``after`` seconds into its run (or once idle), and return how
    many frames it had begun to hand in and how many a reader finds. ``from_first``: ``after``
    counts from the first frame handed in, not from the first frame readable."""
    proc = subprocess.Popen(
        [sys.executable, "-c", KILLED_WRITER, str(path), mode, str(count), str(fps)],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    lines: list[str] = []
    try:
        lines.append(proc.stdout.readline())  # the first frame: the writer is running
        assert lines[0].strip() == "0", lines
        # Past the codecs' start-up (loading depthac's compiled kernels takes a while): the
        # kill comes while recording at a steady 30 fps.
        assert from_first or _poll(lambda: _readable(path) >= 1, timeout=30)
        if mode == "idle":
            while lines[-1].strip() not in ("idle", ""):
                lines.append(proc.stdout.readline())
        time.sleep(after)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    # Every frame number it printed, after the kill included: each was printed before its
    # write() began.
    lines += proc.stdout.read().splitlines()
    handed = sum(1 for line in lines if line.strip().isdigit())
    proc.stdout.close()
    return handed, _readable(path)


@pytest.mark.parametrize("kill", range(3))
def test_sigkill_at_30_fps_loses_at_most_the_frame_being_handed_in(
    tmp_path: Path, kill: int
) -> None:
    rng = random.Random(kill)
    handed, readable = _kill_writer(tmp_path / "k.pcdc", "paced", 10_000, rng.uniform(0.2, 0.6))
    assert handed >= 5
    assert handed - 1 <= readable <= handed


@pytest.mark.parametrize("kill", range(3))
def test_sigkill_from_the_first_frame_on_loses_at_most_the_frame_being_handed_in(
    tmp_path: Path, kill: int
) -> None:
    """The codecs are ready when the writer opens, so its first frames are written as soon as
    later ones: a kill a few frames in loses at most the frame being handed in. (Frames come at
    10 a second, a margin for a busy machine; a writer that readied its codecs at its first
    frame, most of a second, had then written none.)"""
    rng = random.Random(kill)
    path = tmp_path / "k.pcdc"
    handed, readable = _kill_writer(
        path, "paced", 10_000, rng.uniform(0.15, 0.45), fps=10, from_first=True
    )
    assert handed >= 2
    assert handed - 1 <= readable <= handed


@pytest.mark.parametrize("count", [1, 7])
def test_sigkill_of_an_idle_writer_loses_nothing(tmp_path: Path, count: int) -> None:
    handed, readable = _kill_writer(tmp_path / "k.pcdc", "idle", count, random.uniform(0, 0.05))
    assert handed == count
    assert readable == count


@pytest.mark.parametrize(
    "bad",
    [
        {"pts": -5},  # MCAP times are unsigned: met on the writing thread, it damaged the file
        {"pts": 2**64},
        {"dts": 2**63},
        {"data": "not bytes"},
        {"keyframe": "yes"},
    ],
)
def test_write_encoded_refuses_a_packet_the_file_cannot_hold_before_taking_it(
    tmp_path: Path, sample: RGBDSequence, bad: dict[str, Any]
) -> None:
    path = tmp_path / "p.pcdc"
    groups = _encoded_groups(sample, 4)
    with _writer(path, sample, color="h264") as rec:
        for i in range(4):
            if i == 2:
                p = groups[i][0]
                fields = {"data": p.data, "pts": p.pts, "dts": p.dts, "keyframe": p.keyframe}
                broken = Packet(**{**fields, **bad})
                with pytest.raises(pcdcodec.InputError, match="packet 0"):
                    rec.write_encoded([broken], sample[i].depth, i * STEP)
            rec.write_encoded(groups[i], sample[i].depth, i * STEP)
    with pcdcodec.open(path) as back:
        assert back.verify().ok
        assert [int(t) // STEP for t in back.timestamps] == [0, 1, 2, 3]
        assert all(np.array_equal(back[i].depth, sample[i].depth) for i in range(4))


def test_a_background_error_loses_no_pair_of_write_color_and_write_depth(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "s.pcdc"
    # Frame 0's depth fails; with in_flight=1 the failure is known before the third pair is
    # handed in, so it surfaces while the synchronizer hands pairs out.
    rec = _writer(path, sample, depth=_FailingZstd(fail_on=1), in_flight=1)
    raised: list[str] = []

    def hand_in(method: Callable[[Any, int], None], image: Any, timestamp: int) -> None:
        try:
            method(image, timestamp)
        except RuntimeError as exc:  # raised before the image is taken: hand it in again
            raised.append(str(exc))
            method(image, timestamp)

    for i in range(10):
        hand_in(rec.write_depth, sample[i].depth, i * STEP)
        hand_in(rec.write_color, sample[i].color, i * STEP + 1_000_000)
    try:
        rec.close()
    except RuntimeError as exc:
        raised.append(str(exc))
    assert len(raised) == 1
    assert "call 1" in raised[0]
    assert rec.unpaired == {"color": [], "depth": []}
    with pcdcodec.open(path) as back:
        assert [int(t) // STEP for t in back.timestamps] == list(range(1, 10))
        assert back.verify().ok


class _StrZstd(Zstd):
    """Returns a str for its third frame, as a faulty codec might."""

    def __init__(self) -> None:
        super().__init__()
        self._calls = 0

    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        return ("level",)

    def encode(self, depth: npt.ArrayLike) -> bytes:
        self._calls += 1
        return "not bytes" if self._calls == 3 else super().encode(depth)  # type: ignore[return-value]


def test_a_depth_codec_returning_no_bytes_fails_its_frame_only(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "d.pcdc"
    rec = _writer(path, sample, depth=_StrZstd())
    raised: list[str] = []
    for i in range(5):
        try:
            rec.write(sample[i].color, sample[i].depth, i * STEP)
        except pcdcodec.PcdcodecError as exc:  # raised by a later write() or by close()
            raised.append(str(exc))
    try:
        rec.close()
    except pcdcodec.PcdcodecError as exc:
        raised.append(str(exc))
    assert len(raised) == 1
    assert "returned a str" in raised[0]
    with pcdcodec.open(path) as back:
        assert back.verify().ok
        assert [int(t) // STEP for t in back.timestamps] == [0, 1, 3, 4]


def test_an_error_inside_the_file_writer_leaves_the_file_unfinished_not_damaged(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "w.pcdc"
    rec = _writer(path, sample)
    real = rec._mcap.add_message
    calls = 0

    def failing(channel: int, log_time: int, data: bytes, publish: int, seq: int = 0) -> None:
        nonlocal calls
        calls += 1
        if calls == 12:  # a message of the fourth frame: MCAP's writer fails part way
            real(channel, log_time, "half a record", publish, seq)  # type: ignore[arg-type]
        real(channel, log_time, data, publish, seq)

    rec._mcap.add_message = failing  # type: ignore[method-assign]
    raised: list[Exception] = []
    for i in range(8):
        try:
            rec.write(sample[i].color, sample[i].depth, i * STEP)
        except (TypeError, pcdcodec.PcdcodecError) as exc:  # raised by write() or by close()
            raised.append(exc)
    try:
        rec.close()
    except (TypeError, pcdcodec.PcdcodecError) as exc:
        raised.append(exc)
    assert isinstance(raised[0], TypeError)
    # Raised once; a later write() or close() says the frames after it were not written.
    assert all("not written further" in str(exc) for exc in raised[1:])
    # Not sealed over the damage: the file reads as unfinished, with every frame before it.
    with pcdcodec.open(path) as back:
        assert not back.indexed
        assert [int(t) // STEP for t in back.timestamps] == [0, 1, 2]
        assert all(np.array_equal(back[i].depth, sample[i].depth) for i in range(3))
    assert pcdcodec.recording.recover(path, tmp_path / "r.pcdc") == 3


def test_a_file_cut_at_any_byte_reads_every_frame_written_before_the_cut(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    """As after a kill at any point: the frames whose messages all precede the cut read back
    exactly, and recover copies the same frames. Frame 3's depth fails (its color packet stays
    in the file, with the next frame's group) and odd frames carry a pose."""
    step = 8
    i0 = sample.intrinsics
    cam = pcdcodec.CameraIntrinsics(
        i0.width // step, i0.height // step, i0.fx / step, i0.fy / step, i0.cx / step, i0.cy / step
    )
    frames = [(f.color[::step, ::step].copy(), f.depth[::step, ::step].copy()) for f in sample]
    path = tmp_path / "full.pcdc"
    rec = pcdcodec.open(
        path, "w", intrinsics=cam, depth_scale=sample.depth_scale, depth=_FailingZstd(fail_on=4)
    )
    sizes = []  # the file's size once each frame is written
    for k, (color, depth) in enumerate(frames[:7]):
        pose = np.eye(4)
        pose[0, 3] = k / 10
        rec.write(color, depth, k * STEP, pose=pose if k % 2 else None)
        with contextlib.suppress(RuntimeError):
            rec.flush()
        sizes.append(path.stat().st_size)
    rec.abort()
    with pcdcodec.open(path) as back:
        full = [(f.color.copy(), f.depth.copy()) for f in back]
        assert [int(t) // STEP for t in back.timestamps] == [0, 1, 2, 4, 5, 6]
    written = [s for k, s in enumerate(sizes) if k != 3]
    data = path.read_bytes()
    rng = random.Random(5)
    cuts = {s for s in written} | {s - 1 for s in written}
    cuts |= {rng.randrange(written[0], len(data)) for _ in range(25)}
    cut = tmp_path / "cut.pcdc"
    for at in sorted(cuts):
        cut.write_bytes(data[:at])
        with pcdcodec.open(cut) as back:
            n = len(back)
            # The frame is whole once its digest is written; MCAP's index of the chunk follows.
            assert sum(s <= at for s in written) <= n <= sum(s <= at + 64 for s in written)
            for i, f in enumerate(back):
                assert np.array_equal(f.depth, full[i][1])
                assert np.array_equal(f.color, full[i][0])
        assert pcdcodec.recording.recover(cut, tmp_path / "r.pcdc", overwrite=True) == n


def test_in_flight_can_be_changed_on_an_open_writer(tmp_path: Path, sample: RGBDSequence) -> None:
    rec = _writer(tmp_path / "w.pcdc", sample, in_flight=4)
    try:
        rec.in_flight = 1
        assert rec._pipeline.in_flight == 1  # the bound the queue waits on
        with pytest.raises(pcdcodec.InputError, match="in_flight"):
            rec.in_flight = 0
        rec.write(sample[0].color, sample[0].depth, sample[0].timestamp_ns)
    finally:
        rec.close()


# -- the codecs are ready when the writer opens -----------------------------------------------

# In a fresh interpreter (this one may have loaded depthac's loops in an earlier test): opens a
# writer, or a rig of two cameras, and checks that the codecs are ready once open() returns.
# Then no module may be imported, and no compiled loop loaded, while frames are written: the
# first frames cost what later ones do, so none waits behind a one-off start-up.
READY_AT_OPEN = textwrap.dedent(
    """
    import sys, threading
    import pcdcodec
    from pcdcodec.recording.rig import CameraSpec, RigWriter
    path, rig = sys.argv[1], sys.argv[2] == "rig"
    seq = pcdcodec.load_sample(max_frames=3)
    assert "pcdcodec.depth._depthac_kernels" not in sys.modules
    if rig:
        specs = [CameraSpec(n, seq.intrinsics, seq.depth_scale) for n in ("a", "b")]
        rec = RigWriter(path, specs)
        writers = [rec.camera("a"), rec.camera("b")]
    else:
        rec = pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale)
        writers = [rec]
    kernels = sys.modules.get("pcdcodec.depth._depthac_kernels")
    assert kernels is not None and kernels.encode_into.overloads, "depthac's loops not loaded"
    loaded = len(kernels.encode_into.overloads)
    assert all(w._encoder is not None for w in writers), "the video encoder is not open"
    names = {t.name.rsplit("_", 1)[0] for t in threading.enumerate()}
    assert {"pcdcodec-color", "pcdcodec-depth", "pcdcodec-write"} <= names, names
    assert all(w.ready for w in writers)

    class NoImports:
        def find_spec(self, name, path=None, target=None):
            raise ImportError(f"{name} imported while writing frames")

    sys.meta_path.insert(0, NoImports())
    for k, f in enumerate(seq):
        for w in writers:
            w.write(f.color, f.depth, k * 33_000_000)
    for w in writers:
        w.flush()  # raises what went wrong on the threads (an import refused)
    sys.meta_path.pop(0)
    assert len(kernels.encode_into.overloads) == loaded, "a loop was loaded at the first frame"
    rec.close()
    print("ok")
    """
)


@pytest.mark.parametrize("kind", ["writer", "rig"])
def test_the_codecs_are_ready_when_the_writer_opens(tmp_path: Path, kind: str) -> None:
    done = subprocess.run(
        [sys.executable, "-c", READY_AT_OPEN, str(tmp_path / "r.pcdc"), kind],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip() == "ok"
    with pcdcodec.open(tmp_path / "r.pcdc") as back:
        assert back.verify().ok


class _NoEncoderH264(pcdcodec.color.H264):
    """h264 whose encoder cannot open here, as NVENC on a machine without a GPU."""

    def encoder(self, width: int, height: int, fps: float = 30.0) -> Any:
        raise pcdcodec.CodecUnavailableError("no encoder on this machine")


def test_an_encoder_that_cannot_open_is_named_by_the_first_write_not_by_open(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    rec = _writer(tmp_path / "n.pcdc", sample, color=_NoEncoderH264())
    assert not rec.ready  # the encoder did not open; the writer still takes encoded packets
    with pytest.raises(pcdcodec.CodecUnavailableError, match="no encoder"):
        rec.write(sample[0].color, sample[0].depth, 0)
    groups = _encoded_groups(sample, 3)
    for i, group in enumerate(groups):
        rec.write_encoded(group, sample[i].depth, i * STEP)
    assert rec.ready
    rec.close()
    with pcdcodec.open(tmp_path / "n.pcdc") as back:
        assert [p.data for p in back.packets()] == [g[0].data for g in groups]
        assert back.verify().ok


def test_a_writer_that_fails_to_open_leaves_no_thread_running(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    from pcdcodec.recording.rig import CameraSpec, RigWriter

    before = set(threading.enumerate())
    (tmp_path / "there.pcdc").write_bytes(b"")
    with pytest.raises(pcdcodec.InputError, match="already exists"):
        _writer(tmp_path / "there.pcdc", sample)
    specs = [
        CameraSpec("a", sample.intrinsics, sample.depth_scale),
        CameraSpec("b", sample.intrinsics, sample.depth_scale, fps=-1),  # the second fails
    ]
    with pytest.raises(pcdcodec.InputError, match="fps"):
        RigWriter(tmp_path / "rig.pcdc", specs)
    assert not (tmp_path / "rig.pcdc").exists()
    assert set(threading.enumerate()) <= before
