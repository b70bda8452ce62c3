"""Recordings: round trips, random access, crash tolerance, damage and bad input."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.datasets import RGBDSequence, load_sample
from pcdcodec.metrics import psnr
from pcdcodec.recording._index import seal

from .conftest import SEQUENCES, SHARED_SEQUENCES, load_colors, load_depths


@pytest.fixture(scope="module")
def sample() -> RGBDSequence:
    return load_sample()


def record(path: Path, seq: RGBDSequence, **options: Any) -> Path:
    options.setdefault("intrinsics", seq.intrinsics)
    options.setdefault("depth_scale", seq.depth_scale)
    with pcdcodec.open(path, "w", **options) as rec:
        assert rec.write_frames(seq) == len(seq)
    return path


@pytest.fixture(scope="module")
def default_file(tmp_path_factory: pytest.TempPathFactory, sample: RGBDSequence) -> Path:
    return record(tmp_path_factory.mktemp("rec") / "sample.pcdc", sample, metadata={"site": "lab"})


# -- round trips --------------------------------------------------------------------------------


def test_default_round_trip(default_file: Path, sample: RGBDSequence) -> None:
    with pcdcodec.open(default_file) as rec:
        assert len(rec) == len(sample)
        assert rec.indexed
        assert rec.intrinsics == sample.intrinsics
        assert rec.depth_scale == sample.depth_scale
        assert (
            rec.codecs["depth"] == pcdcodec.get_codec(pcdcodec.DEFAULT_DEPTH_CODEC).stored_config()
        )
        assert rec.codecs["color"] == pcdcodec.get_codec("h264").stored_config()
        assert rec.metadata == {"site": "lab"}
        np.testing.assert_array_equal(rec.timestamps, [f.timestamp_ns for f in sample])
        for frame, original in zip(rec, sample, strict=True):
            assert frame.timestamp_ns == original.timestamp_ns
            np.testing.assert_array_equal(frame.depth, original.depth)
            assert frame.depth.dtype == np.uint16
            assert frame.color is not None
            assert psnr(frame.color, original.color) > 32.5


@pytest.mark.parametrize("color", ["ffv1", "h264-lossless"])
def test_lossless_color_round_trip(tmp_path: Path, sample: RGBDSequence, color: str) -> None:
    seq = RGBDSequence(sample.frames[:6], sample.intrinsics, sample.depth_scale)
    path = record(tmp_path / "a.pcdc", seq, color=color, depth="zstd")
    with pcdcodec.open(path) as rec:
        assert rec.codecs["color"]["id"] == color  # type: ignore[index]
        for frame, original in zip(rec, seq, strict=True):
            np.testing.assert_array_equal(frame.color, original.color)
            np.testing.assert_array_equal(frame.depth, original.depth)


@pytest.mark.parametrize("depth", pcdcodec.list_codecs("depth"))
def test_every_depth_codec_round_trips_in_a_recording(
    tmp_path: Path, sample: RGBDSequence, depth: str
) -> None:
    seq = RGBDSequence(sample.frames[:3], sample.intrinsics, sample.depth_scale)
    path = record(tmp_path / "a.pcdc", seq, depth=depth, color="mjpeg")
    with pcdcodec.open(path) as rec:
        for frame, original in zip(rec, seq, strict=True):
            np.testing.assert_array_equal(frame.depth, original.depth)


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", SHARED_SEQUENCES)
def test_shared_sequences_round_trip(tmp_path: Path, sequence: str) -> None:
    depths = load_depths(sequence, 5)
    colors = load_colors(sequence, 5)
    h, w = depths[0].shape
    cam = pcdcodec.CameraIntrinsics(w, h, 525.0, 525.0, w / 2 - 0.5, h / 2 - 0.5)
    path = tmp_path / "s.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=cam, depth_scale=SEQUENCES[sequence].depth_scale
    ) as w_:
        for i, (c, d) in enumerate(zip(colors, depths, strict=True)):
            w_.write(c, d, i * 33_000_000)
    with pcdcodec.open(path) as rec:
        assert len(rec) == 5
        for frame, depth, color in zip(rec, depths, colors, strict=True):
            np.testing.assert_array_equal(frame.depth, depth)
            assert frame.color is not None
            assert psnr(frame.color, color) > 30


def test_depth_only_and_float_metres(tmp_path: Path, sample: RGBDSequence) -> None:
    path = tmp_path / "d.pcdc"
    metres = []
    with pcdcodec.open(
        path, "w", intrinsics=sample.intrinsics, depth_scale=1.0, color=None, depth="lz4"
    ) as rec:
        for i, frame in enumerate(sample.frames[:4]):
            m = (frame.depth / 5000.0).astype(np.float32)
            m[frame.depth == 0] = np.nan
            metres.append(m)
            rec.write(None, m, 1000 + i)
    with pcdcodec.open(path) as rec:
        assert rec.codecs["color"] is None
        assert len(rec) == 4
        frame = rec[2]
        assert frame.color is None
        np.testing.assert_array_equal(frame.depth.view(np.uint32), metres[2].view(np.uint32))
        points, _ = frame.to_points()
        assert len(points) == int(np.isfinite(metres[2]).sum())


def test_a_recording_holds_one_depth_type(tmp_path: Path, sample: RGBDSequence) -> None:
    """uint16 units and float32 values under one depth_scale would read back with one of them
    scaled wrong: the second type is refused, and the frames written before are kept."""
    metres = np.where(sample[0].depth > 0, sample[0].depth / 5000.0, np.nan).astype(np.float32)
    for first, second in ((metres, sample[1].depth), (sample[1].depth, metres)):
        path = tmp_path / f"{first.dtype}.pcdc"
        with pcdcodec.open(
            path, "w", intrinsics=sample.intrinsics, depth_scale=1.0, color=None, depth="zstd"
        ) as w:
            w.write(None, first, 1)
            with pytest.raises(pcdcodec.InputError, match=f"{second.dtype}.*{first.dtype}"):
                w.write(None, second, 2)
            w.write(None, first, 3)
        with pcdcodec.open(path) as rec:
            assert len(rec) == 2
            assert all(f.depth.dtype == first.dtype for f in rec)
            assert np.array_equal(rec[1].depth, first, equal_nan=True)


def test_float_metres_need_the_depth_scale_given(tmp_path: Path, sample: RGBDSequence) -> None:
    """Without depth_scale, float32 metres would be read at the uint16 default of 1000 units per
    metre, 1000x too near: the writer refuses the frame and keeps what was written."""
    metres = np.where(sample[0].depth > 0, sample[0].depth / 5000.0, np.nan).astype(np.float32)
    path = tmp_path / "f.pcdc"
    with pcdcodec.open(path, "w", intrinsics=sample.intrinsics, color=None, depth="zstd") as w:
        w.write(None, sample[0].depth, 1)  # uint16 at the default scale is fine
        with pytest.raises(pcdcodec.InputError, match="depth_scale"):
            w.write(None, metres, 2)
    with pcdcodec.open(path) as rec:
        assert len(rec) == 1
        assert np.array_equal(rec[0].depth, sample[0].depth)
    cam = sample.intrinsics
    rig = tmp_path / "rig.pcdc"
    specs = [
        pcdcodec.CameraSpec("a", cam, color=None, depth="zstd"),
        pcdcodec.CameraSpec("b", cam, 1.0, color=None, depth="zstd"),
    ]
    with pcdcodec.open(rig, "w", cameras=specs) as w:
        w.write("b", None, metres, 1)
        with pytest.raises(pcdcodec.InputError, match="depth_scale"):
            w.write("a", None, metres, 1)
    with pcdcodec.open(rig) as rec:
        points = rec.frames("b")[0].to_points()[0]
        assert np.isclose(np.nanmax(points[:, 2]), np.nanmax(metres))


def test_frames_give_point_clouds_and_rgbd(default_file: Path, sample: RGBDSequence) -> None:
    with pcdcodec.open(default_file) as rec:
        frame = rec[0]
        cloud = frame.to_point_cloud()
        assert len(cloud.points) == int(np.count_nonzero(sample[0].depth))
        tensor = frame.to_point_cloud(tensor=True)
        assert tensor.point.positions.shape[0] == len(cloud.points)
        rgbd = frame.to_open3d_rgbd()
        np.testing.assert_allclose(
            np.asarray(rgbd.depth), sample[0].depth / 5000.0, rtol=1e-6, atol=1e-7
        )
        assert np.asarray(rgbd.color).shape == (480, 640, 3)


def test_write_rgbd_images(tmp_path: Path, sample: RGBDSequence) -> None:
    import open3d as o3d

    path = tmp_path / "o.pcdc"
    with pcdcodec.open(path, "w", intrinsics=sample.intrinsics, depth_scale=5000.0) as rec:
        for frame in sample.frames[:3]:
            rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
                o3d.geometry.Image(frame.color),
                o3d.geometry.Image(frame.depth),
                depth_scale=5000.0,
                depth_trunc=1000.0,
                convert_rgb_to_intensity=False,
            )
            rec.write_rgbd(rgbd, frame.timestamp_ns, depth_scale=5000.0)
    with pcdcodec.open(path) as rec:
        for frame, original in zip(rec, sample.frames[:3], strict=False):
            np.testing.assert_array_equal(frame.depth, original.depth)


# -- random access --------------------------------------------------------------------------


def test_random_access_matches_sequential(tmp_path: Path, sample: RGBDSequence) -> None:
    path = record(tmp_path / "g.pcdc", sample, color=pcdcodec.get_codec("h264", gop=5))
    with pcdcodec.open(path) as rec:
        sequential = [(f.color.copy(), f.depth.copy()) for f in rec]  # type: ignore[union-attr]
    order = np.random.default_rng(1).permutation(len(sample)).tolist()
    with pcdcodec.open(path) as rec:
        for i in order:
            frame = rec[i]
            np.testing.assert_array_equal(frame.color, sequential[i][0])
            np.testing.assert_array_equal(frame.depth, sequential[i][1])
        assert rec[-1].index == len(sample) - 1
        assert [f.index for f in rec[3:9:2]] == [3, 5, 7]
        assert rec.nearest(sample[6].timestamp_ns + 5_000_000).index == 6
        assert rec.nearest(0).index == 0
        with pytest.raises(IndexError, match="15 frames"):
            rec[15]
        with pytest.raises(pcdcodec.InputTypeError):
            rec["3"]


def test_seeking_decodes_only_from_the_previous_keyframe(
    tmp_path: Path, sample: RGBDSequence, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = record(tmp_path / "k.pcdc", sample, color=pcdcodec.get_codec("h264", gop=5))
    with pcdcodec.open(path) as rec:
        read: list[int] = []
        original = rec._packet

        def counting(j: int) -> Any:
            read.append(j)
            return original(j)

        monkeypatch.setattr(rec, "_packet", counting)
        keys = rec._keyframes
        assert keys[0] == 0
        assert max(np.diff(keys)) <= 5  # at least every 5 frames (x264 may add scene cuts)

        def previous_key(i: int) -> int:
            return max(k for k in keys if k <= i)

        rec[12]  # decodes from the keyframe at or before 12, nothing earlier
        assert read == list(range(previous_key(12), 13))
        read.clear()
        rec[13]  # continues from where it stopped, unless 13 is itself a keyframe
        assert read == [13]
        read.clear()
        rec[6]  # back to the keyframe before 6
        assert read == list(range(previous_key(6), 7))


def test_b_frames_in_a_recording(tmp_path: Path, sample: RGBDSequence) -> None:
    path = record(tmp_path / "b.pcdc", sample, color=pcdcodec.get_codec("h264", bframes=2, gop=6))
    with pcdcodec.open(path) as rec:
        forward = [f.color.copy() for f in rec]  # type: ignore[union-attr]
        for i in (9, 2, 14, 7):
            np.testing.assert_array_equal(rec[i].color, forward[i])
        assert [f.timestamp_ns for f in rec] == [f.timestamp_ns for f in sample]


def test_play_paces_frames(default_file: Path) -> None:
    with pcdcodec.open(default_file) as rec:
        start = time.perf_counter()
        frames = list(rec.play(rate=4.0))
        elapsed = time.perf_counter() - start
        assert [f.index for f in frames] == list(range(len(rec)))
        # Sleeping guarantees the lower bound whatever the machine does.
        assert elapsed >= 0.95 * rec.duration / 4.0
        with pytest.raises(pcdcodec.InputError, match="rate"):
            next(rec.play(rate=0))


def test_writer_timestamps_default_to_fps(tmp_path: Path, sample: RGBDSequence) -> None:
    path = tmp_path / "t.pcdc"
    with pcdcodec.open(path, "w", intrinsics=sample.intrinsics, fps=20.0) as rec:
        for frame in sample.frames[:3]:
            rec.write(frame.color, frame.depth)
    with pcdcodec.open(path) as rec:
        assert rec.timestamps.tolist() == [0, 50_000_000, 100_000_000]
        assert rec.fps == 20.0


# -- crash tolerance --------------------------------------------------------------------------

WRITER_SCRIPT = textwrap.dedent(
    """
    import json, sys, pcdcodec
    seq = pcdcodec.load_sample()
    color = json.loads(sys.argv[2])
    with pcdcodec.open(
        sys.argv[1], "w", intrinsics=seq.intrinsics, depth_scale=5000.0, color=color
    ) as rec:
        for loop in range(1000):
            for i, frame in enumerate(seq):
                rec.write(frame.color, frame.depth, (loop * 15 + i) * 33_000_000)
                print(rec.frames_complete, flush=True)
    """
)


@pytest.mark.parametrize(
    ("kill_after", "color"),
    [
        (1, {"id": "h264"}),
        (9, {"id": "h264"}),
        (40, {"id": "h264"}),
        (25, {"id": "h264", "low_delay": False}),
        (20, {"id": "ffv1"}),
    ],
    ids=["h264-after-1", "h264-after-9", "h264-after-40", "h264-lookahead", "ffv1"],
)
def test_sigkill_loses_at_most_the_frames_in_flight(
    tmp_path: Path, sample: RGBDSequence, kill_after: int, color: dict[str, Any]
) -> None:
    path = tmp_path / "killed.pcdc"
    proc = subprocess.Popen(
        [sys.executable, "-c", WRITER_SCRIPT, str(path), json.dumps(color)],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    written = 0
    lines = 0
    for line in proc.stdout:
        lines += 1
        written = int(line)
        if lines >= kill_after:
            break
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    # The writer may have gone on between the last line read and the kill: count every line
    # it printed (each one after a write() returned), so the bounds below hold exactly.
    rest = proc.stdout.read().split()
    lines += len(rest)
    if rest:
        written = int(rest[-1])
    with pcdcodec.open(path) as rec:
        assert not rec.indexed
        # Every frame whose messages were written is there; lost are only those in flight.
        assert written <= len(rec) <= lines
        if color.get("low_delay", True):
            # At the defaults encoders hold nothing back: lost are only the writer's queue
            # (in_flight = 4) and the frame being handed to it.
            assert lines - len(rec) <= 4 + 1
        for frame in rec:
            np.testing.assert_array_equal(frame.depth, sample[frame.index % 15].depth)
            assert frame.color is not None
        assert rec.verify().frames == len(rec)
    recovered = tmp_path / "recovered.pcdc"
    count = pcdcodec.recording.recover(path, recovered)
    with pcdcodec.open(recovered) as rec:
        assert rec.indexed
        assert len(rec) == count
        assert rec.verify().ok
        assert count >= written


def test_truncated_files_keep_every_complete_frame(tmp_path: Path, sample: RGBDSequence) -> None:
    # Without lookahead every frame's packet is written with it, so any cut keeps frames.
    source = record(tmp_path / "src.pcdc", sample, color={"id": "h264", "tune": "zerolatency"})
    data = source.read_bytes()
    with pcdcodec.open(source) as rec:
        full = [(f.timestamp_ns, f.depth.copy()) for f in rec]
    for cut in (len(data) // 3, len(data) // 2, len(data) - 1000):
        path = tmp_path / f"cut{cut}.pcdc"
        path.write_bytes(data[:cut])
        with pcdcodec.open(path) as rec:
            assert 0 < len(rec) <= len(full)
            assert not rec.indexed
            for frame in rec:
                assert frame.timestamp_ns == full[frame.index][0]
                np.testing.assert_array_equal(frame.depth, full[frame.index][1])
            report = rec.verify()
            assert not report.indexed
            if cut < len(data) // 2 + 1:  # cut inside the data: reported with its offset
                assert not report.ok
                assert "cut short" in report.errors[0]


# -- damage -----------------------------------------------------------------------------------


def test_corrupt_depth_names_the_frame_and_offset(tmp_path: Path, default_file: Path) -> None:
    with pcdcodec.open(default_file) as rec:
        offset = int(rec._offsets[4])
    data = bytearray(default_file.read_bytes())
    data[offset + 200] ^= 0xFF
    path = tmp_path / "bad.pcdc"
    path.write_bytes(bytes(data))
    with pcdcodec.open(path) as rec:
        with pytest.raises(pcdcodec.DecodeError, match=f"frame 4.*byte offset {offset}"):
            rec[4]
        np.testing.assert_array_equal(rec[5].depth, load_sample(6)[5].depth)
        report = rec.verify()
        assert not report.ok
        assert len(report.errors) == 1
        assert "frame 4" in report.errors[0]


def test_corrupt_color_packet_is_reported(tmp_path: Path, default_file: Path) -> None:
    with pcdcodec.open(default_file) as rec:
        offset = int(rec._packet_offsets[3])
    data = bytearray(default_file.read_bytes())
    data[offset + 300] ^= 0x01
    path = tmp_path / "badc.pcdc"
    path.write_bytes(bytes(data))
    with pcdcodec.open(path) as rec:
        with pytest.raises(pcdcodec.DecodeError, match=f"byte offset {offset}"):
            rec[3]
        assert any("frame 3" in e for e in rec.verify().errors)


# -- bad input ----------------------------------------------------------------------------------


def test_existing_file_is_never_overwritten_by_accident(
    tmp_path: Path, sample: RGBDSequence, default_file: Path
) -> None:
    path = tmp_path / "keep.pcdc"
    path.write_bytes(default_file.read_bytes())
    before = path.read_bytes()
    with pytest.raises(pcdcodec.InputError, match="overwrite=True"):
        pcdcodec.open(path, "w", intrinsics=sample.intrinsics)
    assert path.read_bytes() == before
    # With overwrite the old file stays whole until the new one is complete.
    with pcdcodec.open(path, "w", intrinsics=sample.intrinsics, overwrite=True) as rec:
        rec.write(sample[0].color, sample[0].depth, 1)
        assert path.read_bytes() == before
    with pcdcodec.open(path) as rec:
        assert len(rec) == 1


def test_bad_frames_are_refused_and_the_recording_survives(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "r.pcdc"
    with pcdcodec.open(path, "w", intrinsics=sample.intrinsics, depth_scale=5000.0) as rec:
        rec.write(sample[0].color, sample[0].depth, 100)
        with pytest.raises(pcdcodec.InputError, match="100 ns does not increase"):
            rec.write(sample[1].color, sample[1].depth, 100)
        with pytest.raises(pcdcodec.InputError, match="differs from the depth size"):
            rec.write(sample[1].color[:, :320], sample[1].depth, 200)
        with pytest.raises(pcdcodec.InputError, match="320x480"):
            rec.write(sample[1].color[:, :320], sample[1].depth[:, :320], 200)
        with pytest.raises(pcdcodec.InputTypeError, match="int64"):
            rec.write(sample[1].color, sample[1].depth.astype(np.int64), 200)
        with pytest.raises(pcdcodec.InputError, match="has color"):
            rec.write(None, sample[1].depth, 200)
        rec.write(sample[1].color, sample[1].depth, 200)
    with pcdcodec.open(path) as rec:
        assert rec.timestamps.tolist() == [100, 200]
        assert rec.verify().ok


def test_writer_argument_errors(tmp_path: Path, sample: RGBDSequence) -> None:
    with pytest.raises(pcdcodec.InputError, match="intrinsics are required"):
        pcdcodec.open(tmp_path / "x.pcdc", "w", intrinsics=None)
    small = pcdcodec.CameraIntrinsics(320, 240, 262.5, 262.5, 159.5, 119.5)
    with (
        pcdcodec.open(tmp_path / "y.pcdc", "w", intrinsics=small) as rec,
        pytest.raises(pcdcodec.InputError, match="intrinsics are for 320x240"),
    ):
        rec.write(sample[0].color, sample[0].depth, 1)
    with pytest.raises(pcdcodec.UnknownCodecError, match="'h263'"):
        pcdcodec.open(tmp_path / "z.pcdc", "w", intrinsics=sample.intrinsics, color="h263")
    with pytest.raises(pcdcodec.UnknownCodecError, match="depth codec"):
        pcdcodec.open(tmp_path / "z.pcdc", "w", intrinsics=sample.intrinsics, depth="h264")
    with pytest.raises(pcdcodec.InputError, match="depth_scale"):
        pcdcodec.open(tmp_path / "z.pcdc", "w", intrinsics=sample.intrinsics, depth_scale=-1.0)
    with pytest.raises(pcdcodec.InputError, match="mode"):
        pcdcodec.open(tmp_path / "z.pcdc", "a")
    assert not (tmp_path / "z.pcdc").exists()


def test_paths_that_are_not_recordings(tmp_path: Path) -> None:
    with pytest.raises(pcdcodec.InputError, match="does not exist"):
        pcdcodec.open(tmp_path / "missing.pcdc")
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    with pytest.raises(pcdcodec.DecodeError, match="not a pcdcodec recording"):
        pcdcodec.open(text)
    from mcap.writer import Writer

    other = tmp_path / "other.mcap"
    with other.open("wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="x")
        w.finish()
    with pytest.raises(pcdcodec.DecodeError, match="profile 'ros2'"):
        pcdcodec.open(other)
    with pytest.raises(pcdcodec.InputError, match="folder"):
        pcdcodec.open(tmp_path)


def _rewrite_metadata(src: Path, dst: Path, **changes: str) -> None:
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    with src.open("rb") as f, dst.open("wb") as out:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        w = Writer(out, chunk_size=0, compression=CompressionType.NONE)
        w.start(profile="pcdcodec", library="test")
        for meta in reader.iter_metadata():
            data = dict(meta.metadata)
            if meta.name == "pcdcodec":
                data.update(changes)
                data = seal(meta.name, data)  # as a writer of such a file would
            w.add_metadata(meta.name, data)
        ids = {}
        for sid, schema in summary.schemas.items():
            ids[sid] = w.register_schema(schema.name, schema.encoding, schema.data)
        channels = {}
        for cid, ch in summary.channels.items():
            channels[cid] = w.register_channel(
                ch.topic, ch.message_encoding, ids.get(ch.schema_id, 0), ch.metadata
            )
        for _, channel, message in reader.iter_messages(log_time_order=False):
            w.add_message(
                channels[channel.id],
                message.log_time,
                message.data,
                message.publish_time,
                message.sequence,
            )
        w.finish()


def test_newer_format_version_is_refused(tmp_path: Path, default_file: Path) -> None:
    path = tmp_path / "v9.pcdc"
    _rewrite_metadata(default_file, path, format_version="9")
    with pytest.raises(pcdcodec.DecodeError, match=r"format version 9.*upgrade"):
        pcdcodec.open(path)


def test_unknown_codec_in_a_file_is_named(tmp_path: Path, default_file: Path) -> None:
    path = tmp_path / "unk.pcdc"
    _rewrite_metadata(default_file, path, depth_codec=json.dumps({"id": "depth-from-mars"}))
    with pytest.raises(pcdcodec.UnknownCodecError, match="depth-from-mars"):
        pcdcodec.open(path)


def test_rewritten_file_still_reads(tmp_path: Path, default_file: Path) -> None:
    """A file rewritten by another MCAP writer (several messages per chunk) reads the same."""
    from mcap.reader import make_reader

    path = tmp_path / "same.pcdc"
    _rewrite_metadata(default_file, path)
    with pcdcodec.open(path) as a, pcdcodec.open(default_file) as b:
        assert len(a) == len(b)
        np.testing.assert_array_equal(a[7].depth, b[7].depth)
    with path.open("rb") as f:
        assert make_reader(f).get_summary() is not None


def test_separate_color_and_depth_streams_are_synchronized(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "sync.pcdc"
    frames = sample.frames[:8]
    with pcdcodec.open(path, "w", intrinsics=sample.intrinsics, depth_scale=5000.0) as rec:
        for i, frame in enumerate(frames):
            t = 1_000_000_000 + i * 33_000_000
            rec.write_color(frame.color, t + 3_000_000)  # color 3 ms after depth
            if i != 5:  # one depth image lost on the way
                rec.write_depth(frame.depth, t)
        # A color image far from any depth finds no partner.
        rec.write_color(frames[0].color, 1_000_000_000 + 9 * 33_000_000)
    assert rec.unpaired["color"] == [
        1_000_000_000 + 5 * 33_000_000 + 3_000_000,
        1_000_000_000 + 9 * 33_000_000,
    ]
    assert rec.unpaired["depth"] == []
    with pcdcodec.open(path) as out:
        kept = [i for i in range(8) if i != 5]
        assert len(out) == len(kept)
        assert out.timestamps.tolist() == [1_000_000_000 + i * 33_000_000 for i in kept]
        for frame, i in zip(out, kept, strict=True):
            np.testing.assert_array_equal(frame.depth, frames[i].depth)
            assert psnr(frame.color, frames[i].color) > 32  # type: ignore[arg-type]


def test_b_frames_with_timestamps_from_zero(tmp_path: Path, sample: RGBDSequence) -> None:
    path = tmp_path / "zero.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=sample.intrinsics, color={"id": "h264", "bframes": 2}
    ) as rec:
        for frame in sample.frames[:6]:
            rec.write(frame.color, frame.depth)  # 0, 33 ms, ...: the first dts are negative
    with pcdcodec.open(path) as rec:
        assert rec.timestamps.tolist()[:2] == [0, 33_333_333]
        assert all(f.color is not None for f in rec)


@pytest.mark.parametrize("color", ["mpeg4", "h264"])
def test_decoding_is_repeatable(tmp_path: Path, sample: RGBDSequence, color: str) -> None:
    path = record(tmp_path / "rep.pcdc", sample, color=color)
    results = []
    for _ in range(4):
        with pcdcodec.open(path) as rec:
            results.append([f.color.tobytes() for f in rec])  # type: ignore[union-attr]
    assert all(r == results[0] for r in results)
