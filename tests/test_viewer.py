"""pcdcodec view: a recording in Rerun, checked through the .rrd file it writes, read back with
Rerun's own reader: depth bit-exact, color packets as recorded, points only when asked."""

from __future__ import annotations

import dataclasses
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.cli import main

pytest.importorskip("rerun")


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    seq = pcdcodec.load_sample(max_frames=4)
    path = tmp_path_factory.mktemp("view") / "v.pcdc"
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=5000.0) as w:
        # Without the sample's poses (its groundtruth.txt): the trajectory is tested below.
        w.write_frames(dataclasses.replace(f, pose=None) for f in seq)
    return path


def _contents(rrd: Path) -> dict[str, dict[str, Any]]:
    """Per entity: its columns, and the rows of its last chunk on the frame timeline."""
    from rerun.chunk import RrdReader

    out: dict[str, dict[str, Any]] = {}
    for chunk in RrdReader(rrd).stream():
        batch = chunk.to_record_batch()
        entry = out.setdefault(chunk.entity_path, {"columns": set(), "frames": []})
        entry["columns"].update(batch.schema.names)
        if "frame" in batch.schema.names:
            entry["frames"] += batch.column("frame").to_pylist()
        entry.setdefault("batches", []).append(batch)
    return out


def _blobs(batch: Any, column: str) -> list[bytes]:
    """The one blob of each row of a ``list<list<uint8>>`` column, as bytes."""
    outer = batch.column(column)
    return [bytes(outer[i].values[0].values.to_numpy()) for i in range(len(outer))]


def _logged_depths(entry: dict[str, Any]) -> dict[int, np.ndarray[Any, Any]]:
    """Frame number -> the depth image an ``EncodedDepthImage`` entity holds, decoded (PNG with
    imagecodecs, RVL after its 20-byte compressedDepth header with pcdcodec's decoder)."""
    import imagecodecs

    from pcdcodec.depth.rvl import rvl_decode

    out = {}
    for batch in entry["batches"]:
        if "EncodedDepthImage:blob" not in batch.schema.names:
            continue
        media = [m[0] for m in batch.column("EncodedDepthImage:media_type").to_pylist()]
        for f, blob, kind in zip(
            batch.column("frame").to_pylist(),
            _blobs(batch, "EncodedDepthImage:blob"),
            media,
            strict=True,
        ):
            if kind == "image/png":
                out[f] = imagecodecs.png_decode(blob)
            else:
                assert kind == "application/rvl"
                _, quant_a, quant_b, width, height = struct.unpack("<iffII", blob[:20])
                assert (quant_a, quant_b) == (0.0, 0.0)  # Rerun: no quantization, plain uint16
                out[f] = rvl_decode(memoryview(blob[20:]), width * height).reshape(height, width)
    return out


def test_view_logs_depth_lossless_and_the_color_packets_as_recorded(
    recording: Path, tmp_path: Path
) -> None:
    from pcdcodec.viewer import view

    with pcdcodec.open(recording) as rec:
        depths = [rec.depth(i) for i in range(len(rec))]
        packets = [p.data for p in rec.packets()]
        scale = rec.depth_scale
    for depth_format in ("png", "rvl"):
        out = view(recording, save=tmp_path / f"{depth_format}.rrd", depth_format=depth_format)
        assert out is not None
        got = _contents(out)
        entry = got["/world/camera/image/depth"]
        logged = _logged_depths(entry)
        assert sorted(logged) == [0, 1, 2, 3]
        for i, depth in enumerate(depths):
            assert logged[i].dtype == np.uint16
            assert np.array_equal(logged[i], depth)  # bit-exact
        meters = {
            m[0] for b in entry["batches"] for m in b.column("EncodedDepthImage:meter").to_pylist()
        }
        assert meters == {scale}
        assert "DepthImage:buffer" not in entry["columns"]
        rgb = got["/world/camera/image/rgb"]
        codec = [b for b in rgb["batches"] if "VideoStream:codec" in b.schema.names]
        assert codec[0].column("VideoStream:codec").to_pylist() == [[0x61766331]]  # H.264
        samples = [
            blob for b in rgb["batches"] if "VideoStream:sample" in b.schema.names
            for blob in _blobs(b, "VideoStream:sample")
        ]  # fmt: skip
        assert samples == packets  # passed through, not re-encoded
        assert sorted(rgb["frames"]) == [0, 1, 2, 3]
        assert "/world/camera/points" not in got  # Rerun draws the cloud from the depth image
        if depth_format == "png":  # the default: at most 3 times the recording
            assert out.stat().st_size < 3 * recording.stat().st_size


def test_view_saves_color_depth_points_camera_over_time(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out.rrd"
    args = ["view", str(recording), "--save", str(out), "--stride", "4", "--points"]
    assert main(args) == 0
    assert "wrote" in capsys.readouterr().out
    assert out.exists()
    assert not list(tmp_path.glob(".out.rrd.partial*"))
    got = _contents(out)
    assert "Pinhole:image_from_camera" in got["/world/camera"]["columns"]
    assert sorted(got["/world/camera/image/rgb"]["frames"]) == [0, 1, 2, 3]
    assert sorted(got["/world/camera/image/depth"]["frames"]) == [0, 1, 2, 3]
    assert "EncodedDepthImage:meter" in got["/world/camera/image/depth"]["columns"]
    points = got["/world/camera/points"]
    assert sorted(points["frames"]) == [0, 1, 2, 3]
    assert "time" in points["columns"]
    # The cloud of frame 0 at stride 4: its points are those of every 4th pixel with depth.
    first = points["batches"][0].column("Points3D:positions").to_pylist()[0]
    depth = pcdcodec.load_sample(max_frames=1)[0].depth[::4, ::4]
    assert len(first) == int(np.count_nonzero(depth))
    assert "/world/trajectory" not in got  # this recording has no poses


def test_view_logs_the_trajectory_where_poses_exist(tmp_path: Path) -> None:
    from pcdcodec.viewer import view

    seq = pcdcodec.load_sample(max_frames=4)
    recording = tmp_path / "posed.pcdc"
    with pcdcodec.open(recording, "w", intrinsics=seq.intrinsics, depth_scale=5000.0) as w:
        for i, frame in enumerate(seq):
            pose = np.eye(4)
            pose[:3, 3] = [0.1 * i, 0.0, 0.0]
            w.write_frames([dataclasses.replace(frame, pose=pose)])
    out = view(recording, save=tmp_path / "p.rrd", every=2)
    assert out == tmp_path / "p.rrd"
    got = _contents(out)
    # One static line through the positions of the frames shown.
    strips = got["/world/trajectory"]["batches"][0].column("LineStrips3D:strips").to_pylist()
    assert np.allclose(np.asarray(strips[0][0]), [[0.0, 0, 0], [0.2, 0, 0]])
    assert got["/world/trajectory"]["frames"] == []
    assert "Transform3D:translation" in got["/world/camera"]["columns"]
    # Every color packet up to the last frame shown: a video decodes from its keyframe on;
    # those of frames not shown are on timeline "time" alone.
    rgb = got["/world/camera/image/rgb"]
    assert sorted(rgb["frames"]) == [0, 2]
    samples = sum(b.num_rows for b in rgb["batches"] if "VideoStream:sample" in b.schema.names)
    assert samples == 3


def test_view_threads_reads_ahead_and_logs_the_same(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pcdcodec.recording.reader import Recording

    read_ahead = []
    in_order = Recording._in_order

    def spy(self: Recording, start: int) -> Any:
        read_ahead.append(self.threads)
        return in_order(self, start)

    monkeypatch.setattr(Recording, "_in_order", spy)
    logged = {}
    for threads in ("1", "2"):
        out = tmp_path / f"t{threads}.rrd"
        args = ["view", str(recording), "--save", str(out), "--threads", threads, "--points"]
        assert main([*args, "--max-frames", "3"]) == 0
        got = _contents(out)
        points = got["/world/camera/points"]
        assert sorted(points["frames"]) == [0, 1, 2]
        # Row by row: how Rerun batches rows into chunks depends on timing.
        logged[threads] = [
            row for b in points["batches"] for row in b.column("Points3D:positions").to_pylist()
        ]
    assert read_ahead == [1, 2]  # every frame in order, on the threads asked for
    assert logged["2"] == logged["1"]
    assert main(["view", str(recording), "--save", str(tmp_path / "x.rrd"), "--threads", "-2"]) == 1


def test_view_rejects_bad_options(recording: Path, tmp_path: Path) -> None:
    from pcdcodec.viewer import view

    with pytest.raises(pcdcodec.InputError, match="stride"):
        view(recording, save=tmp_path / "x.rrd", stride=0)
    with pytest.raises(pcdcodec.InputError, match="folder"):
        view(recording, save=tmp_path)
    with pytest.raises(pcdcodec.InputError, match="max_frames must be None or a positive int"):
        view(recording, save=tmp_path / "x.rrd", max_frames=2.5)  # type: ignore[arg-type]
    for quality in (0, 101, "x"):
        with pytest.raises(pcdcodec.InputError, match=f"jpeg_quality .* got {quality!r}"):
            view(recording, save=tmp_path / "x.rrd", jpeg_quality=quality)  # type: ignore[arg-type]
    with pytest.raises(pcdcodec.InputError, match="no folder"):
        view(recording, save=tmp_path / "missing" / "x.rrd")
    assert list(tmp_path.iterdir()) == []


def test_view_leaves_no_partial_file_when_the_recording_fails(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A frame that fails to decode midway (here: its second frame) leaves nothing behind. (A
    file cut short is no such failure: its readable frames are shown.)"""
    from pcdcodec import viewer

    log_frame = viewer._log_frame
    calls: list[int] = []

    def failing(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        if len(calls) == 2:
            raise pcdcodec.DecodeError("frame 1: damaged")
        return log_frame(*args, **kwargs)

    monkeypatch.setattr(viewer, "_log_frame", failing)
    with pytest.raises(pcdcodec.DecodeError, match="frame 1: damaged"):
        viewer.view(recording, save=tmp_path / "v.rrd")
    assert list(tmp_path.iterdir()) == []


def test_view_open3d_checks_its_options_before_opening_a_window(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import open3d as o3d

    from pcdcodec.viewer import view_open3d

    windows = []

    class Visualizer:
        def create_window(self, **_: Any) -> bool:
            windows.append(self)
            return False

        def destroy_window(self) -> None:
            pass

    monkeypatch.setattr(o3d.visualization, "Visualizer", Visualizer)
    for options, match in (
        ({"every": 0}, "every must be a positive int"),
        ({"every": -2}, "every must be a positive int"),
        ({"fps": -1.0}, "fps must be positive"),
        ({"threads": -1}, r"threads must be an int in 0\.\.256"),
    ):
        with pytest.raises(pcdcodec.InputError, match=match):
            view_open3d(recording, **options)
    with pytest.raises(pcdcodec.InputError, match="does not exist"):
        view_open3d(tmp_path / "missing.pcdc")
    assert not windows
    with pytest.raises(pcdcodec.PcdcodecError, match="could not open a window"):
        view_open3d(recording, threads=2)
    assert len(windows) == 1


def _color_recording(path: Path, color: str, frames: int = 3) -> Path:
    seq = pcdcodec.load_sample(max_frames=frames)
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=5000.0, color=color) as w:
        w.write_frames(dataclasses.replace(f, pose=None) for f in seq)
    return path


def test_view_logs_mjpeg_packets_and_other_codecs_as_jpeg_images(tmp_path: Path) -> None:
    from pcdcodec.viewer import view

    for color in ("mjpeg", "ffv1"):
        recording = _color_recording(tmp_path / f"{color}.pcdc", color)
        got = _contents(view(recording, save=tmp_path / f"{color}.rrd"))  # type: ignore[arg-type]
        rgb = got["/world/camera/image/rgb"]
        assert sorted(rgb["frames"]) == [0, 1, 2]
        assert "VideoStream:sample" not in rgb["columns"]
        images = [blob for b in rgb["batches"] for blob in _blobs(b, "EncodedImage:blob")]
        assert all(blob.startswith(b"\xff\xd8") for blob in images)  # JPEG
        if color == "mjpeg":  # the recording's own JPEGs
            with pcdcodec.open(recording) as rec:
                assert images == [p.data for p in rec.packets()]
    # Asked for images: the H.264 recording's color decoded and logged as JPEG too.
    recording = _color_recording(tmp_path / "h264.pcdc", "h264")
    out = tmp_path / "h.rrd"
    assert main(["view", str(recording), "--save", str(out), "--no-video", "--depth", "rvl"]) == 0
    got = _contents(out)
    assert "EncodedImage:blob" in got["/world/camera/image/rgb"]["columns"]
    assert len(_logged_depths(got["/world/camera/image/depth"])) == 3  # RVL
    # B-frames: packets out of display order, which Rerun's VideoStream cannot take.
    recording = _color_recording(tmp_path / "b.pcdc", "h264:bframes=2", frames=6)
    with pcdcodec.open(recording) as rec:
        assert not np.all(np.diff(rec.packet_timestamps) > 0)
    got = _contents(view(recording, save=tmp_path / "b.rrd"))  # type: ignore[arg-type]
    assert "VideoStream:sample" not in got["/world/camera/image/rgb"]["columns"]
    assert sorted(got["/world/camera/image/rgb"]["frames"]) == list(range(6))


def test_view_falls_back_to_raw_depth_and_jpeg_without_the_newer_archetypes(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import rerun as rr

    from pcdcodec.viewer import view

    # Rerun releases before VideoStream (0.24) and EncodedDepthImage have neither.
    monkeypatch.delattr(rr, "EncodedDepthImage")
    monkeypatch.delattr(rr, "VideoStream")
    got = _contents(view(recording, save=tmp_path / "old.rrd"))  # type: ignore[arg-type]
    depth = got["/world/camera/image/depth"]
    assert "DepthImage:buffer" in depth["columns"]
    assert "EncodedDepthImage:blob" not in depth["columns"]
    with pcdcodec.open(recording) as rec:
        buffers = [b for b in depth["batches"] if "DepthImage:buffer" in b.schema.names]
        first = np.frombuffer(_blobs(buffers[0], "DepthImage:buffer")[0], np.uint16)
        assert np.array_equal(first.reshape(rec.intrinsics.shape), rec.depth(0))
    assert "EncodedImage:blob" in got["/world/camera/image/rgb"]["columns"]


def test_view_logs_float_depth_raw(tmp_path: Path) -> None:
    from pcdcodec.viewer import view

    seq = pcdcodec.load_sample(max_frames=2)
    recording = tmp_path / "f.pcdc"
    for scale in (1.0, 1000.0):  # float32 metres, and float32 millimetres
        recording = tmp_path / f"f{scale}.pcdc"
        with pcdcodec.open(
            recording, "w", intrinsics=seq.intrinsics, depth_scale=scale, depth="zstd"
        ) as w:
            for f in seq:
                units = np.where(f.depth > 0, f.depth / np.float32(5000.0 / scale), np.nan)
                w.write_frames([dataclasses.replace(f, depth=units.astype(np.float32), pose=None)])
        out = tmp_path / f"f{scale}.rrd"
        got = _contents(view(recording, save=out, points=True))  # type: ignore[arg-type]
        # Neither PNG nor RVL holds float32 depth: Rerun's raw DepthImage, with its depth units
        # per metre, which put it where the points logged beside it are.
        depth = got["/world/camera/image/depth"]
        assert "DepthImage:buffer" in depth["columns"]
        meters = [m for b in depth["batches"] for m in b.column("DepthImage:meter").to_pylist()]
        assert meters == [[scale], [scale]]
        points = got["/world/camera/points"]["batches"][0].column("Points3D:positions")
        z = np.array(points.to_pylist()[0])[:, 2]
        assert 0.5 < float(np.median(z)) < 5  # metres, for both scales


def test_view_rejects_a_depth_format_it_does_not_know(recording: Path, tmp_path: Path) -> None:
    from pcdcodec.viewer import view

    with pytest.raises(pcdcodec.InputError, match="depth_format must be one of"):
        view(recording, save=tmp_path / "x.rrd", depth_format="jpeg")


def test_live_view_logs_big_endian_depth_as_its_values(tmp_path: Path) -> None:
    import imagecodecs

    from pcdcodec.geometry.projector import Projector
    from pcdcodec.viewer import LiveView

    seq = pcdcodec.load_sample(max_frames=1)
    projector = Projector(seq.intrinsics, seq.depth_scale)
    depth = seq[0].depth
    metres = (depth / np.float32(seq.depth_scale)).astype(">f4")
    for name, image in (("u16", depth.astype(">u2")), ("f32", metres)):
        out = tmp_path / f"live_{name}.rrd"
        live = LiveView([("cam", projector)], save=out)
        assert live.log(0, pcdcodec.Frame(None, image, 0, projector=projector))
        live.close()
        batch = _contents(out)["/world/cam/depth"]["batches"][0]
        if name == "u16":  # a PNG of the values
            logged = imagecodecs.png_decode(_blobs(batch, "EncodedDepthImage:blob")[0])
            assert np.array_equal(logged, depth)
        else:  # raw: Rerun takes the buffer as little-endian float32
            raw = bytes(batch.column("DepthImage:buffer").to_pylist()[0][0])
            logged = np.frombuffer(raw, "<f4").reshape(depth.shape)
            assert np.array_equal(logged, metres)


def test_live_view_logs_depth_lossless_and_points_only_when_asked(tmp_path: Path) -> None:
    import imagecodecs

    from pcdcodec.geometry.projector import Projector
    from pcdcodec.viewer import LiveView

    seq = pcdcodec.load_sample(max_frames=1)
    frame = seq[0]
    projector = Projector(seq.intrinsics, 5000.0)
    for points in (False, True):
        out = tmp_path / f"live{points}.rrd"
        live = LiveView([("cam", projector)], save=out, points=points)
        assert live.log(0, frame)
        live.close()
        got = _contents(out)
        logged = [
            imagecodecs.png_decode(blob)
            for b in got["/world/cam/depth"]["batches"]
            for blob in _blobs(b, "EncodedDepthImage:blob")
        ]
        assert len(logged) == 1
        assert np.array_equal(logged[0], frame.depth)
        assert ("/world/cam/points" in got) == points


@pytest.mark.parametrize(("color", "fourcc"), [("h265", 0x68657631), ("av1", 0x61763031)])
def test_view_passes_h265_and_av1_packets_through(color: str, fourcc: int, tmp_path: Path) -> None:
    from pcdcodec.registry import list_codecs
    from pcdcodec.viewer import view

    if color not in list_codecs("color", available_only=True):
        pytest.skip(f"{color} is not available here")
    recording = _color_recording(tmp_path / f"{color}.pcdc", color)
    got = _contents(view(recording, save=tmp_path / f"{color}.rrd"))  # type: ignore[arg-type]
    rgb = got["/world/camera/image/rgb"]["batches"]
    codec = [
        b.column("VideoStream:codec").to_pylist()
        for b in rgb
        if "VideoStream:codec" in b.schema.names
    ]
    assert codec == [[[fourcc]]]
    samples = [
        blob for b in rgb if "VideoStream:sample" in b.schema.names
        for blob in _blobs(b, "VideoStream:sample")
    ]  # fmt: skip
    with pcdcodec.open(recording) as rec:
        assert samples == [p.data for p in rec.packets()]


def test_view_encodes_depth_ahead_on_threads_in_order(recording: Path, tmp_path: Path) -> None:
    from pcdcodec.viewer import view

    with pcdcodec.open(recording) as rec:
        depths = [rec.depth(i) for i in range(len(rec))]
    for threads in (1, 3):
        out = view(recording, save=tmp_path / f"t{threads}.rrd", threads=threads)
        logged = _logged_depths(_contents(out)["/world/camera/image/depth"])  # type: ignore[arg-type]
        assert sorted(logged) == list(range(len(depths)))
        assert all(np.array_equal(logged[i], d) for i, d in enumerate(depths))
    out = view(recording, save=tmp_path / "e.rrd", threads=2, every=3)
    logged = _logged_depths(_contents(out)["/world/camera/image/depth"])  # type: ignore[arg-type]
    assert sorted(logged) == [0, 3]
    assert np.array_equal(logged[3], depths[3])


def test_view_points_take_their_colors_through_the_color_camera(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=1)
    cam, frame = seq.intrinsics, seq[0]
    small = pcdcodec.CameraIntrinsics(320, 240, cam.fx / 2, cam.fy / 2, cam.cx / 2, cam.cy / 2)
    path = tmp_path / "two.pcdc"
    with pcdcodec.open(
        path,
        "w",
        intrinsics=cam,
        depth_scale=seq.depth_scale,
        color_intrinsics=small,
        depth_to_color=np.eye(4),
        color="mjpeg",  # every frame a JPEG, kept as recorded, so the colors compare exactly
    ) as w:
        w.write(np.ascontiguousarray(frame.color[::2, ::2]), frame.depth, frame.timestamp_ns)
    out = tmp_path / "out.rrd"
    assert main(["view", str(path), "--save", str(out), "--points", "--stride", "2"]) == 0
    batch = _contents(out)["/world/camera/points"]["batches"][0]
    positions = np.array(batch.column("Points3D:positions").to_pylist()[0], np.float32)
    colors = batch.column("Points3D:colors").to_pylist()[0]
    with pcdcodec.open(path) as rec:
        decoded = rec[0]
        thinned = np.zeros_like(decoded.depth)
        thinned[::2, ::2] = decoded.depth[::2, ::2]
        want, want_colors = rec.projector.to_points(thinned, decoded.color)
    assert want_colors is not None
    assert np.array_equal(positions, want)
    packed = [int.from_bytes(bytes([*c, 255]), "big") for c in want_colors.tolist()]
    assert colors == packed
