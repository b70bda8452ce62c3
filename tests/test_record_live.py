"""Live RealSense recording, without a camera: librealsense plays ``.bag`` files back as devices.

The bags are the real D435 bag in ../shared/data and bags made from the real D435 office
sequence (pcdcodec.bench.realsense_bags); every frame is checked against the same bag read by
pcdcodec's own reader (RealSenseBagSource). Skipped when pyrealsense2 or the data is absent.
"""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.realsense_bags import TEMPLATE_BAG, write_realsense_bag
from pcdcodec.bench.sequences import SEQUENCES, read_image
from pcdcodec.cli import main
from pcdcodec.cli.capture import Camera, Capture, CaptureStats
from pcdcodec.cli.live import _Status, camera_names
from pcdcodec.errors import InputError, PcdcodecError
from pcdcodec.frame import Frame
from pcdcodec.sources.realsense import RealSenseBagSource

FRAMES = 24
#: frame counters of the made bag: the camera "dropped" frames 10 and 11
NUMBERS = [i if i < 10 else i + 2 for i in range(FRAMES)]


@pytest.fixture(scope="module")
def rs() -> Any:
    return pytest.importorskip("pyrealsense2")


def _made_bag(
    path: Path,
    serial: str,
    count: int = FRAMES,
    start_ns: int = 10**10,
    color_delays_ns: list[int] | None = None,
) -> Path:
    seq = SEQUENCES["realsense_d435"]
    if not (seq.present and TEMPLATE_BAG.is_file()):
        pytest.skip("the shared RealSense data is not present")
    depths = [read_image(p) for p in seq.depth_paths()[:count]]
    colors = [read_image(p)[..., :3] for p in sorted(seq.root.glob(seq.color_glob))[:count]]
    numbers = NUMBERS[:count] if count == FRAMES else None
    return write_realsense_bag(
        path,
        depths,
        colors,
        serial=serial,
        intrinsics=seq.camera,
        frame_numbers=numbers,
        start_ns=start_ns,
        color_delays_ns=color_delays_ns,
    )


@pytest.fixture(scope="module")
def bag(rs: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _made_bag(tmp_path_factory.mktemp("rs") / "office.bag", "000000000001")


@pytest.fixture(scope="module")
def reference(bag: Path) -> dict[int, Frame]:
    """The made bag's frames as pcdcodec's own .bag reader gives them, by timestamp."""
    with RealSenseBagSource(bag) as source:
        return {f.timestamp_ns: f for f in source}


def _digest(depth: np.ndarray[Any, Any]) -> str:
    return hashlib.sha1(np.ascontiguousarray(depth).tobytes()).hexdigest()


# -- the source ---------------------------------------------------------------------------


@pytest.mark.shared_data
def test_real_bag_plays_back_bit_exact_with_the_bag_readers_camera(rs: Any) -> None:
    if not TEMPLATE_BAG.is_file():
        pytest.skip(f"{TEMPLATE_BAG} is not present")
    wide = 300_000_000  # the bag's only color frame is 268 ms before its last depth frame
    with pcdcodec.sources.realsense_live(playback=TEMPLATE_BAG, color=False) as live:
        depths = {f.timestamp_ns: f.depth for f in live}
    with RealSenseBagSource(TEMPLATE_BAG, max_difference=wide) as ref:
        paired = list(ref)
        assert ref.dropped == {"color": 0, "depth": 1}
        with pcdcodec.sources.realsense_live(playback=TEMPLATE_BAG, max_difference=wide) as live:
            got = list(live)
            assert live.intrinsics == ref.intrinsics
            assert live.color_intrinsics == ref.color_intrinsics
            assert live.depth_scale == ref.depth_scale == 1000.0
            np.testing.assert_allclose(live.depth_to_color, ref.depth_to_color, atol=1e-6)
            for key in ("device", "serial", "firmware"):
                assert live.metadata[key] == ref.metadata[key]
            assert live.metadata["timestamp_domain"] == "hardware_clock"
            assert live.dropped == {"color": 0, "depth": 0}
    # Depth alone, the playback hands over both depth frames, bit-exact with the bag reader's.
    assert len(depths) == 2
    assert len(paired) == 1
    assert np.array_equal(depths[paired[0].timestamp_ns], paired[0].depth)
    # With color, librealsense hands over the last depth frame only (with the color frame),
    # while the bag reader pairs that color with the nearer, first depth frame.
    assert [f.timestamp_ns for f in got] == [max(depths)]
    assert np.array_equal(got[0].depth, depths[max(depths)])
    assert np.array_equal(got[0].color, paired[0].color)


@pytest.mark.shared_data
@pytest.mark.parametrize("align", [False, True])
def test_real_bag_at_the_default_limit_pairs_nothing_as_the_bag_reader(
    rs: Any, align: bool
) -> None:
    if not TEMPLATE_BAG.is_file():
        pytest.skip(f"{TEMPLATE_BAG} is not present")
    with RealSenseBagSource(TEMPLATE_BAG) as ref:
        assert list(ref) == []
        assert ref.dropped == {"color": 1, "depth": 2}
    with pcdcodec.sources.realsense_live(playback=TEMPLATE_BAG, align=align) as live:
        assert live.max_difference == pcdcodec.sync.MAX_DIFFERENCE
        assert list(live) == []
        # the one depth frame librealsense hands over, and the color frame 268 ms before it
        assert live.dropped == {"color": 1, "depth": 1}
        assert live.describe()["dropped"] == live.dropped


@pytest.fixture(scope="module")
def late_bag(rs: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """12 frames, color frame 5 stamped 25 ms after its depth frame (8.3 ms before the next)."""
    delays = [25_000_000 if i == 5 else 0 for i in range(12)]
    path = tmp_path_factory.mktemp("rs") / "late.bag"
    return _made_bag(path, "000000000002", count=12, color_delays_ns=delays)


@pytest.mark.shared_data
@pytest.mark.parametrize("align", [False, True])
def test_live_playback_drops_and_reports_what_the_bag_reader_drops(
    late_bag: Path, align: bool
) -> None:
    with RealSenseBagSource(late_bag) as ref:
        reference = {f.timestamp_ns: f for f in ref}
        dropped = ref.dropped
    # color 5 is 25 ms from depth 5, over the 20 ms limit, and depth 6 has its own color
    assert dropped == {"color": 1, "depth": 1}
    assert len(reference) == 11
    with pcdcodec.sources.realsense_live(playback=late_bag, align=align) as live:
        frames = list(live)
        assert live.dropped == dropped
    assert [f.timestamp_ns for f in frames] == sorted(reference)
    for frame in frames:
        assert np.array_equal(frame.depth, reference[frame.timestamp_ns].depth)
        if not align:
            assert np.array_equal(frame.color, reference[frame.timestamp_ns].color)
    # a wider limit pairs color 5 with depth 5, in both readers
    wide = 30_000_000
    with RealSenseBagSource(late_bag, max_difference=wide) as ref:
        assert len(list(ref)) == 12
    with pcdcodec.sources.realsense_live(playback=late_bag, max_difference=wide) as live:
        assert len(list(live)) == 12
        assert live.dropped == {"color": 0, "depth": 0}


def test_max_difference_is_checked(rs: Any) -> None:
    if not TEMPLATE_BAG.is_file():
        pytest.skip(f"{TEMPLATE_BAG} is not present")
    from pcdcodec.errors import InputTypeError

    with pytest.raises(InputTypeError, match="max_difference"):
        pcdcodec.sources.realsense_live(playback=TEMPLATE_BAG, max_difference=0.02)
    with pytest.raises(InputError, match="max_difference"):
        pcdcodec.sources.realsense_live(playback=TEMPLATE_BAG, max_difference=-1)


@pytest.mark.shared_data
def test_made_bag_plays_back_every_frame_bit_exact(bag: Path, reference: dict[int, Frame]) -> None:
    with pcdcodec.sources.realsense_live(playback=bag) as live:
        frames = list(live)
        assert live.camera_drops == {"depth": 2, "color": 2}  # the gap in the frame counters
        assert live.metadata["serial"] == "000000000001"
    assert [f.timestamp_ns for f in frames] == sorted(reference)
    for frame in frames:
        ref = reference[frame.timestamp_ns]
        assert frame.depth.dtype == np.uint16
        assert np.array_equal(frame.depth, ref.depth)
        assert np.array_equal(frame.color, ref.color)


@pytest.mark.shared_data
def test_aligned_color_has_the_depth_cameras_size(bag: Path, reference: dict[int, Frame]) -> None:
    with pcdcodec.sources.realsense_live(playback=bag, align=True, max_frames=5) as live:
        frames = list(live)
        assert live.color_intrinsics is None
        assert live.depth_to_color is None
    assert len(frames) == 5
    for frame in frames:
        assert frame.color is not None
        assert frame.color.shape == (*frame.depth.shape, 3)
        assert np.array_equal(frame.depth, reference[frame.timestamp_ns].depth)


@pytest.mark.shared_data
def test_looped_playback_keeps_time_increasing(bag: Path, reference: dict[int, Frame]) -> None:
    with pcdcodec.sources.realsense_live(
        playback=bag, loop=True, color=False, max_frames=2 * FRAMES + 5
    ) as live:
        frames = list(live)
    stamps = np.array([f.timestamp_ns for f in frames])
    assert len(frames) == 2 * FRAMES + 5
    assert np.all(np.diff(stamps) > 0)
    first = sorted(reference)
    period = first[1] - first[0]
    # The second pass is the first shifted to start one period after its last frame.
    shift = first[-1] + period - first[0]
    for frame in frames[FRAMES : 2 * FRAMES]:
        assert np.array_equal(frame.depth, reference[frame.timestamp_ns - shift].depth)
        assert frame.color is None


@pytest.mark.shared_data
def test_encode_takes_the_live_source(
    bag: Path, reference: dict[int, Frame], tmp_path: Path
) -> None:
    out = tmp_path / "enc.pcdc"
    with pcdcodec.sources.realsense_live(playback=bag, max_frames=5) as live:
        assert pcdcodec.encode(live, out).frames == 5
    with pcdcodec.open(out) as rec:
        assert rec.metadata["source"] == "realsense-live"
        for frame in rec:
            assert np.array_equal(frame.depth, reference[frame.timestamp_ns].depth)


def test_frame_counters_keep_time_increasing_and_count_gaps() -> None:
    from pcdcodec.sources.live import _Counter

    counter = _Counter()
    assert counter.new(5, 100)
    assert not counter.new(5, 100)  # the same frame in the next frameset
    assert counter.new(8, 200)
    assert counter.dropped == 2
    assert not counter.new(9, 150)  # earlier than the last frame: never handed on
    assert counter.new(0, 300)  # a looped file starts its numbers again: not a gap
    assert counter.dropped == 2


def test_options_are_checked(rs: Any, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="loop=True repeats a playback file"):
        pcdcodec.sources.realsense_live(loop=True)
    with pytest.raises(InputError, match="is not a file"):
        pcdcodec.sources.realsense_live(playback=tmp_path / "missing.bag")
    with pytest.raises(InputError, match="sync must be one of"):
        pcdcodec.sources.realsense_live(playback=tmp_path / "x.bag", sync="leader")


def test_without_pyrealsense2_the_error_says_how_to_install(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    with pytest.raises(PcdcodecError, match=r'pip install "pcdcodec\[realsense\]"'):
        pcdcodec.sources.realsense_live()


def test_import_pcdcodec_does_not_load_pyrealsense2() -> None:
    code = (
        "import sys, pcdcodec, pcdcodec.sources as s; f = s.realsense_live; "
        "print('pyrealsense2' in sys.modules, f.__name__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "realsense_live"]


# -- the capture loop ---------------------------------------------------------------------


class _FakeSource:
    """A camera whose frames all arrive at once, before the writer takes any."""

    def __init__(self, count: int, arrived: threading.Event) -> None:
        self.count, self.arrived = count, arrived
        self.camera_drops = {"depth": 3, "color": 0}

    def __iter__(self) -> Any:
        depth = np.ones((4, 4), np.uint16)
        for i in range(self.count):
            yield Frame(None, depth, i)
        self.arrived.set()


def test_a_full_queue_drops_frames_and_counts_them() -> None:
    arrived = threading.Event()
    written: list[int] = []

    def write(index: int, frame: Frame) -> None:
        arrived.wait(10)  # the encoder is slower than the camera
        written.append(frame.timestamp_ns)

    camera = Camera("cam0", _FakeSource(50, arrived))
    capture = Capture([camera], write, lambda: 100, queue_size=3)
    capture.run()
    assert camera.captured == 50
    assert camera.written == len(written) <= 1 + 3  # the one being written, and the queue
    assert camera.dropped_by_us == 50 - len(written)
    assert written == sorted(written)
    stats = capture.stats()
    assert stats.cameras[0]["camera_drops"] == 3
    assert stats.points == 16 * len(written)
    assert stats.ratio == pytest.approx(32 * 16 * len(written) / 100)


def test_a_blocking_capture_drops_nothing() -> None:
    arrived = threading.Event()
    arrived.set()
    written: list[int] = []
    camera = Camera("cam0", _FakeSource(50, arrived))
    Capture(
        [camera], lambda i, f: written.append(f.timestamp_ns), lambda: 1, queue_size=2, block=True
    ).run()
    assert written == list(range(50))
    assert camera.dropped_by_us == 0


def test_a_camera_error_is_raised_after_writing_what_came_before() -> None:
    def frames() -> Any:
        yield Frame(None, np.ones((2, 2), np.uint16), 1)
        raise PcdcodecError("the camera went away")

    written: list[int] = []
    capture = Capture(
        [Camera("cam0", frames())], lambda i, f: written.append(1), lambda: 1, block=True
    )
    with pytest.raises(PcdcodecError, match="went away"):
        capture.run()
    assert written == [1]


def test_status_line_and_the_warning_when_compression_falls_behind(
    capsys: pytest.CaptureFixture[str],
) -> None:
    cams = (
        {"name": "head", "fps": 29.9, "camera_drops": 1, "dropped_by_us": 0, "points": 10},
        {"name": "wrist", "fps": 30.0, "camera_drops": 0, "dropped_by_us": 4, "points": 10},
    )
    stats = CaptureStats(12.0, cams, 64, 2.5)
    line = stats.line()
    assert "head 29.9 fps, dropped 1 by camera 0 by us" in line
    assert "wrist 30.0 fps, dropped 0 by camera 4 by us" in line
    assert "2.50 MB/s, ratio 10.0x | compression behind" in line
    status = _Status(quiet=False)
    status(stats)
    err = capsys.readouterr().err
    assert "warning: compression cannot keep up with wrist" in err


def test_camera_names() -> None:
    assert camera_names(None, ["123", "456"]) == ["rs_123", "rs_456"]
    assert camera_names(None, ["123", "123"]) == ["cam0", "cam1"]
    assert camera_names(None, [None]) == ["cam0"]
    assert camera_names(["head", "wrist"], ["1", "2"]) == ["head", "wrist"]
    with pytest.raises(InputError, match="one name per camera"):
        camera_names(["head"], ["1", "2"])
    with pytest.raises(InputError, match="must differ"):
        camera_names(["a", "a"], ["1", "2"])


# -- the command --------------------------------------------------------------------------


@pytest.mark.shared_data
def test_record_one_camera_from_playback(
    bag: Path, reference: dict[int, Frame], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.pcdc"
    assert main(["record", "-o", str(out), "--playback", str(bag), "-q"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {FRAMES} frames of 1 camera(s)" in printed
    assert "dropped by the camera: 2 depth / 2 color, dropped by us: 0" in printed
    with pcdcodec.open(out) as rec:
        assert len(rec) == FRAMES
        assert rec.metadata["serial"] == "000000000001"
        assert rec.metadata["timestamp_domain"] == "hardware_clock"
        assert rec.color_intrinsics is not None
        assert rec.depth_to_color is not None
        for frame in rec:
            assert np.array_equal(frame.depth, reference[frame.timestamp_ns].depth)
        assert rec.verify().ok


@pytest.mark.shared_data
def test_record_pairs_within_max_difference_and_says_what_it_dropped(
    late_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.pcdc"
    assert main(["record", "-o", str(out), "--playback", str(late_bag), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "wrote 11 frames of 1 camera(s)" in printed
    assert "dropped 1 color and 1 depth images without a partner within 20 ms" in printed
    wide = tmp_path / "wide.pcdc"
    args = ["record", "-o", str(wide), "--playback", str(late_bag), "--max-difference", "30ms"]
    assert main([*args, "-q"]) == 0
    printed = capsys.readouterr().out
    assert "wrote 12 frames of 1 camera(s)" in printed
    assert "without a partner" not in printed
    with pcdcodec.open(wide) as rec:
        assert len(rec) == 12
    bad = tmp_path / "bad.pcdc"
    for value in ("30", "-1ms"):
        args = ["record", "-o", str(bad), "--playback", str(late_bag), f"--max-difference={value}"]
        assert main(args) != 0
        err = capsys.readouterr().err
        assert f"--max-difference {value!r} is not a duration with its unit" in err
    args = ["record", "-o", str(bad), "--playback", str(late_bag), "--depth-only"]
    assert main([*args, "--max-difference", "30ms"]) != 0
    assert "--depth-only has no color" in capsys.readouterr().err
    assert not bad.exists()


@pytest.mark.shared_data
def test_record_streams_to_a_rerun_file(bag: Path, tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    out, rrd = tmp_path / "run.pcdc", tmp_path / "view.rrd"
    args = ["record", "-o", str(out), "--playback", str(bag), "--frames", "3"]
    assert main([*args, "--view-save", str(rrd), "--align", "-q"]) == 0
    assert rrd.stat().st_size > 1000
    with pcdcodec.open(out) as rec:
        assert len(rec) == 3
        assert rec.color_intrinsics is None


@pytest.mark.shared_data
def test_ctrl_c_finishes_the_file(bag: Path, reference: dict[int, Frame], tmp_path: Path) -> None:
    out = tmp_path / "run.pcdc"
    cmd = [sys.executable, "-m", "pcdcodec", "record", "-o", str(out), "--playback", str(bag)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen(
        [*cmd, "--loop", "--real-time"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        deadline = time.monotonic() + 120
        while not (out.exists() and out.stat().st_size > 200_000):  # frames are being written
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert "stopped by Ctrl-C" in stdout
    written = int(stdout.split("wrote ")[1].split()[0])
    depths = {_digest(f.depth) for f in reference.values()}
    with pcdcodec.open(out) as rec:
        assert len(rec) == written > 0
        assert rec.verify().ok
        for frame in rec:
            assert _digest(frame.depth) in depths


def test_record_without_a_camera_says_so(
    rs: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.sources.live import connected_serials

    if connected_serials():
        pytest.skip("a RealSense camera is connected")
    assert main(["record", "-o", str(tmp_path / "x.pcdc")]) == 1
    assert "no RealSense camera is connected" in capsys.readouterr().err
    assert not (tmp_path / "x.pcdc").exists()


@pytest.mark.shared_data
def test_several_cameras_in_one_recording(rs: Any, tmp_path: Path) -> None:
    a = _made_bag(tmp_path / "a.bag", "111", count=6)
    b = _made_bag(tmp_path / "b.bag", "222", count=6, start_ns=10**10 + 5_000_000)
    out = tmp_path / "rig.pcdc"
    args = ["record", "-o", str(out), "--playback", str(a), "--playback", str(b), "-q"]
    assert main(args) == 0
    with pcdcodec.open(out) as rec:
        assert list(rec.cameras) == ["rs_111", "rs_222"]
        assert rec.metadata["rs_111.serial"] == "111"
        for name, path in (("rs_111", a), ("rs_222", b)):
            with RealSenseBagSource(path) as source:
                ref = {f.timestamp_ns: f.depth for f in source}
            frames = list(rec.frames(camera=name))
            assert len(frames) == 6
            for frame in frames:
                assert np.array_equal(frame.depth, ref[frame.timestamp_ns])


@pytest.mark.shared_data
def test_a_rig_file_names_and_places_the_cameras(
    rs: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = _made_bag(tmp_path / "a.bag", "111", count=4)
    b = _made_bag(tmp_path / "b.bag", "222", count=4)
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "frame: base_link\n"
        "cameras:\n"
        "  - name: head\n"
        "    extrinsic: {translation: [0.1, 0.0, 0.5], rotation: [0.0, 0.0, 0.0, 1.0]}\n"
        "  - name: wrist\n"
        "    color: none\n"
        "    depth: zstd\n"
    )
    out = tmp_path / "rig.pcdc"
    args = ["record", "-o", str(out), "--playback", str(a), "--playback", str(b), "-q"]
    assert main([*args, "--rig", str(rig)]) == 0
    with pcdcodec.open(out) as rec:
        assert list(rec.cameras) == ["head", "wrist"]
        assert rec.rig_frame_id == "base_link"
        np.testing.assert_allclose(rec.rig_poses["head"][:3, 3], [0.1, 0.0, 0.5])
        np.testing.assert_allclose(rec.rig_poses["wrist"], np.eye(4))
        wrist = rec.frames(camera="wrist")
        assert len(wrist) == 4
        assert wrist[0].color is None
    rig.write_text("cameras:\n  - name: head\n    source: a.bag\n  - name: wrist\n")
    assert main([*args, "--rig", str(rig), "--overwrite"]) == 1
    assert "source cannot be set for a live camera" in capsys.readouterr().err
    assert main([*args, "--rig", str(rig), "--name", "x", "--name", "y", "--overwrite"]) == 1
    assert "--name or in the --rig file, not both" in capsys.readouterr().err
