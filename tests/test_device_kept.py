"""Camera files keep what they hold: a RealSense ``.bag``'s every topic not made into frames
(IMU, infrared, options, per-frame metadata, stream infos) byte for byte, and an Azure Kinect
``.mkv``'s IR track (compressed losslessly, bit-exact), IMU blocks and attachments."""

from __future__ import annotations

import collections
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.errors import DecodeError, InputError
from pcdcodec.sources import open_source

from .conftest import SHARED_DATA

BAGS = SHARED_DATA / "bags"
REALSENSE = BAGS / "realsense" / "single_depth_color_640x480.bag"
MKV = BAGS / "pyk4a_recording.mkv"


def _cli(*args: str) -> str:
    out = subprocess.run(
        [sys.executable, "-m", "pcdcodec", *args], capture_output=True, text=True, check=False
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def _ros1_messages(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Every topic's (log time, raw bytes), read with rosbags' own ROS 1 reader."""
    from rosbags.rosbag1 import Reader

    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    with Reader(path) as reader:
        for c, t, raw in reader.messages():
            out[c.topic].append((t, bytes(raw)))
    return dict(out)


def _kept(rec_path: Path) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    with pcdcodec.open(rec_path) as rec:
        for m in rec.kept_messages():
            out[m.topic.topic].append((m.log_time, m.data))
    return dict(out)


# -- RealSense .bag ----------------------------------------------------------------------------


@pytest.mark.skipif(not REALSENSE.exists(), reason=f"{REALSENSE} is not present")
def test_realsense_bag_keeps_its_68_other_topics_byte_for_byte(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Reader

    frames = {"/device_0/sensor_0/Depth_0/image/data", "/device_0/sensor_1/Color_0/image/data"}
    want = {t: m for t, m in _ros1_messages(REALSENSE).items() if t not in frames}
    assert len(want) == 68
    out = tmp_path / "rs.pcdc"
    summary = pcdcodec.encode(REALSENSE, out, max_difference=300_000_000)
    assert summary.left_out == []
    assert {k["name"]: k["messages"] for k in summary.kept} == {t: len(m) for t, m in want.items()}
    assert _kept(out) == want
    with Reader(REALSENSE) as reader:
        conns = {c.topic: c for c in reader.connections}
    with pcdcodec.open(out) as rec:
        assert len(rec) == summary.frames
        for t in rec.kept_topics:
            c = conns[t.topic]
            assert (t.msgtype, t.message_encoding) == (c.msgtype, "ros1")
            assert t.definition == c.msgdef.data  # realsense_msgs/StreamInfo among them
            assert t.metadata["md5sum"] == c.digest


def _rs_bag_with_infrared(path: Path, mono: str) -> Path:
    """A small librealsense bag with an infrared stream (``mono``: mono8 for Y8, mono16 for
    Y16) and an accelerometer's IMU topic beside depth and color."""
    from .camera_file_fuzz import BagRecord, _header, _typestore, rs_image, rs_spec, write_bag

    spec = rs_spec()
    ts = _typestore()
    t = ts.types
    rng = np.random.default_rng(5)
    ir_topic = "/device_0/sensor_0/Infrared_1/image/data"
    vec = t["geometry_msgs/msg/Vector3"]
    for k in range(3):
        stamp = 1_000_000_000 + k * 33_000_000
        dtype = np.uint8 if mono == "mono8" else np.dtype("<u2")
        ir = rng.integers(0, 255 if mono == "mono8" else 65535, (6, 8)).astype(dtype)
        spec.records.append(
            BagRecord(ir_topic, "sensor_msgs/msg/Image", stamp + 2, rs_image(ts, stamp, ir, mono))
        )
        imu = t["sensor_msgs/msg/Imu"](
            header=_header(ts, stamp),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.zeros(9),
            angular_velocity=vec(x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=vec(x=0.1 * k, y=9.8, z=0.0),
            linear_acceleration_covariance=np.zeros(9),
        )
        spec.records.append(
            BagRecord("/device_0/sensor_2/Accel_0/imu/data", "sensor_msgs/msg/Imu", stamp, imu)
        )
    write_bag(spec, path)
    return path


@pytest.mark.parametrize("mono", ["mono8", "mono16"])
def test_realsense_infrared_and_imu_are_kept_and_patterns_choose(mono: str, tmp_path: Path) -> None:
    path = _rs_bag_with_infrared(tmp_path / "ir.bag", mono)
    ir, accel = "/device_0/sensor_0/Infrared_1/image/data", "/device_0/sensor_2/Accel_0/imu/data"
    with open_source(path) as src:
        assert type(src).__name__ == "RealSenseBagSource"
        assert src.left_out == ()
        frames = {src.depth_topic, src.color_topic}
    want = {t: m for t, m in _ros1_messages(path).items() if t not in frames}
    assert {ir, accel} <= set(want)
    out = tmp_path / "ir.pcdc"
    summary = pcdcodec.encode(path, out)
    assert summary.frames == 3
    assert summary.left_out == []
    assert _kept(out) == want
    if mono == "mono16":
        return
    # The command line chooses them as for any bag, and names what it leaves out.
    cli = tmp_path / "cli.pcdc"
    text = _cli("encode", str(path), "-o", str(cli), "--exclude-topic", "*/Infrared_1/*")
    assert ir in text.split("left out")[1]
    assert set(_kept(cli)) == set(want) - {ir}
    only = tmp_path / "only.pcdc"
    _cli("encode", str(path), "-o", str(only), "--include-topic", "/device_0/sensor_2/*")
    assert _kept(only) == {accel: want[accel]}
    with open_source(path, exclude_topics=["*/Accel_0/*"]) as src:
        assert [s.name for s in src.left_out] == [accel]


# -- Azure Kinect .mkv -------------------------------------------------------------------------


def _mkv_tracks(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Every track's (pts, block bytes) and every attachment's (0, bytes), read with PyAV as
    the data's README says."""
    import av

    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    with av.open(str(path)) as container:
        for s in container.streams:
            if s.type == "attachment":
                out[dict(s.metadata)["filename"]].append((0, bytes(s.data)))  # type: ignore[attr-defined]
        for p in container.demux():
            if p.size:
                out[dict(p.stream.metadata)["title"]].append((int(p.pts), bytes(p)))
    return dict(out)


def _ir_images(blocks: list[tuple[int, bytes]], shape: tuple[int, int]) -> list[np.ndarray]:
    return [np.frombuffer(b, ">u2").reshape(shape).astype(np.uint16) for _, b in blocks]


@pytest.mark.skipif(not MKV.exists(), reason=f"{MKV} is not present")
def test_azure_kinect_keeps_ir_bit_exact_and_imu_and_calibration_byte_for_byte(
    tmp_path: Path,
) -> None:
    tracks = _mkv_tracks(MKV)
    out = tmp_path / "k.pcdc"
    summary = pcdcodec.encode(MKV, out)
    assert summary.left_out == []
    kept = {k["name"]: k for k in summary.kept}
    assert set(kept) == {"/k4a/ir", "/k4a/imu", "/k4a/attachment/calibration.json"}
    with pcdcodec.open(out) as rec:
        frame_time = rec[0].timestamp_ns
        ir = list(rec.kept_images("/k4a/ir"))
        got = {m.topic.topic: m for m in rec.kept_messages()}
        topics = {t.topic: t for t in rec.kept_topics}
    (want_ir,) = _ir_images(tracks["IR"], (576, 640))
    assert len(ir) == 1
    assert ir[0][1].dtype == np.uint16
    assert np.array_equal(ir[0][1], want_ir)
    assert ir[0][0] == frame_time  # the IR image of the capture, at the capture's time
    assert got["/k4a/imu"].data == tracks["IMU"][0][1]
    assert got["/k4a/attachment/calibration.json"].data == tracks["calibration.json"][0][1]
    assert MKV.read_bytes().count(got["/k4a/attachment/calibration.json"].data) == 1
    assert topics["/k4a/ir"].message_encoding == "pcdcodec.depth"
    assert dict(topics["/k4a/ir"].metadata)["width"] == "640"
    assert topics["/k4a/imu"].message_encoding == "k4a.imu_sample"
    from pcdcodec.depth.base import read_header

    assert read_header(got["/k4a/ir"].data).codec == "depthac"  # the recording's depth codec
    raw = want_ir.nbytes
    print(
        f"\nIR 640x576: {raw} bytes raw, {kept['/k4a/ir']['bytes']} kept with depthac "
        f"({raw / kept['/k4a/ir']['bytes']:.2f}x)"
    )
    assert kept["/k4a/ir"]["bytes"] < raw / 2


def _k4a_mkv(path: Path, captures: int, *, damaged_ir: bool = False) -> dict[str, Any]:
    """A k4arecorder-like file: color, depth, a 16-bit IR track, an IMU track of 3 samples a
    capture, and a second attachment. Returns what it holds."""
    from .camera_file_fuzz import _bih, _block, _track, _uint, mkv_spec, serialize

    spec = mkv_spec(captures)
    rng = np.random.default_rng(21)
    spec.tracks.append(
        _track(3, 0x0111_2222_3333_4444, "IR", _bih(320, 288, 16, b"b16g", 320 * 288 * 2), 320, 288)
    )
    imu_track = [0xD7, _uint(4)], [0x73C5, _uint(0x0555_6666_7777_8888)], [0x83, b"\x11"]
    spec.tracks.append([0xAE, [*imu_track, [0x86, b"S_K4A/IMU"], [0x536E, b"IMU"]]])
    irs, imus = [], []
    for k, cluster in enumerate(spec.clusters):
        ir = rng.integers(0, 3000, (288, 320)).astype(np.uint16)
        ir[:10] = 65535  # saturated rows, as an IR image near a reflector has
        payload = ir.astype(">u2").tobytes()
        if damaged_ir and k == 1:
            payload = payload[:-2]
        cluster[1].append(_block(3, 0, payload))
        irs.append(ir)
        for j in range(3):
            sample = np.zeros(1, "<u8,3<f4,<u8,3<f4")
            sample[0] = (k * 33_333_000 + j * 5_000_000, (0.1 * j, 9.8, 0.0), k, (0.0, 0.0, j))
            cluster[1].append(_block(4, j * 5000, sample.tobytes()))
            imus.append(sample.tobytes())
    notes = b"a file the recording tool attached\n"
    elements = spec.elements()
    attachments = next(el for el in elements[1][1] if el[0] == 0x1941A469)
    attachments[1].append(
        [0x61A7, [[0x466E, b"notes.txt"], [0x4660, b"text/plain"], [0x465C, notes],
                  [0x46AE, _uint(0x7654321)]]]
    )  # fmt: skip
    path.write_bytes(b"".join(serialize(e) for e in elements))
    return {"ir": irs, "imu": imus, "notes": notes}


def test_synthetic_mkv_keeps_every_ir_image_imu_block_and_attachment(tmp_path: Path) -> None:
    path = tmp_path / "ir.mkv"
    held = _k4a_mkv(path, 4)
    tracks = _mkv_tracks(path)
    assert [b for _, b in tracks["IMU"]] == held["imu"]  # what PyAV reads is what was written
    with open_source(path) as src:
        assert src.left_out == ()
        assert [t.topic for t in src.kept_topics()] == [
            "/k4a/ir", "/k4a/imu", "/k4a/attachment/calibration.json",
            "/k4a/attachment/notes.txt",
        ]  # fmt: skip
        counts = {k["name"]: k["messages"] for k in src.describe()["kept"]}
    assert counts == {
        "/k4a/ir": 4, "/k4a/imu": 12, "/k4a/attachment/calibration.json": 1,
        "/k4a/attachment/notes.txt": 1,
    }  # fmt: skip
    out = tmp_path / "ir.pcdc"
    summary = pcdcodec.encode(path, out)
    assert summary.frames == 4
    assert summary.left_out == []
    with pcdcodec.open(out) as rec:
        times = [f.timestamp_ns for f in rec]
        ir = list(rec.kept_images("/k4a/ir"))
        kept = collections.defaultdict(list)
        for m in rec.kept_messages():
            kept[m.topic.topic].append(m)
        assert rec.verify().ok
    assert [t for t, _ in ir] == times  # each IR image at its capture's time
    for (_, got), want in zip(ir, held["ir"], strict=True):
        assert got.dtype == np.uint16
        assert np.array_equal(got, want)
    assert [m.data for m in kept["/k4a/imu"]] == held["imu"]
    assert [m.log_time for m in kept["/k4a/imu"]] == [
        t + j * 5_000_000 for t in times for j in range(3)
    ]
    from pcdcodec.sources.azure_kinect import imu_samples

    samples = imu_samples(b"".join(m.data for m in kept["/k4a/imu"]))
    assert samples["acc"][4].tolist() == pytest.approx([0.1, 9.8, 0.0])
    assert [m.data for m in kept["/k4a/attachment/notes.txt"]] == [held["notes"]]
    notes = kept["/k4a/attachment/notes.txt"][0].topic
    assert dict(notes.metadata) == {"filename": "notes.txt", "mimetype": "text/plain"}
    with pcdcodec.open(out) as rec, pytest.raises(InputError, match="no images on '/k4a/imu'"):
        next(rec.kept_images("/k4a/imu"))


def test_mkv_ir_codec_follows_a_lossless_recording_and_patterns_leave_tracks_out(
    tmp_path: Path,
) -> None:
    from pcdcodec.depth.base import read_header

    path = tmp_path / "ir.mkv"
    _k4a_mkv(path, 2)

    def ir_codec(rec_path: Path) -> str:
        with pcdcodec.open(rec_path) as rec:
            return {read_header(m.data).codec for m in rec.kept_messages(["/k4a/ir"])}.pop()

    pcdcodec.encode(path, tmp_path / "zstd.pcdc", depth="zstd")
    assert ir_codec(tmp_path / "zstd.pcdc") == "zstd"
    # A lossy depth codec leaves the IR with depthac: it stays lossless.
    pcdcodec.encode(path, tmp_path / "lossy.pcdc", depth="depthac:max_error=2")
    assert ir_codec(tmp_path / "lossy.pcdc") == "depthac"
    pcdcodec.encode(path, tmp_path / "rvl.pcdc", depth="zstd", ir_codec="rvl")
    assert ir_codec(tmp_path / "rvl.pcdc") == "rvl"
    with pytest.raises(InputError, match="ir_codec 'depthac' is lossy"):
        open_source(path, ir_codec="depthac:max_error=2")

    with open_source(path, exclude_topics=["/k4a/imu", "/k4a/attachment/*"]) as src:
        # (calibration.json is read for the cameras: recorded, never left out)
        assert [(s.name, s.count) for s in src.left_out] == [("IMU", 6), ("notes.txt", None)]
        assert [t.topic for t in src.kept_topics()] == ["/k4a/ir"]
    text = _cli("encode", str(path), "-o", str(tmp_path / "cli.pcdc"), "--exclude-topic", "/k4a/ir")
    assert "IR " in text.split("left out")[1]
    with pcdcodec.open(tmp_path / "cli.pcdc") as rec:
        assert "/k4a/ir" not in rec.kept_counts()
        assert rec.kept_counts()["/k4a/imu"] == 6


def test_mkv_depth_only_keeps_the_color_blocks_as_they_are(tmp_path: Path) -> None:
    path = tmp_path / "ir.mkv"
    _k4a_mkv(path, 2)
    color = [b for _, b in _mkv_tracks(path)["COLOR"]]
    out = tmp_path / "d.pcdc"
    with open_source(path, color=False) as src:
        summary = pcdcodec.encode(src, out)
    assert summary.left_out == []
    with pcdcodec.open(out) as rec:
        assert rec.color_codec is None
        got = [m for m in rec.kept_messages(["/k4a/color"])]
    assert [m.data for m in got] == color
    assert got[0].topic.message_encoding == "matroska.block"
    assert dict(got[0].topic.metadata)["codec"] == "MJPG"


def test_mkv_with_a_damaged_ir_block_is_refused_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.mkv"
    _k4a_mkv(path, 3, damaged_ir=True)
    with pytest.raises(DecodeError, match=r"bad\.mkv.*IR block at pts .* holds 184318 bytes"):
        pcdcodec.encode(path, tmp_path / "bad.pcdc")
    assert not (tmp_path / "bad.pcdc").exists()
    # Leaving the IR out records the rest.
    summary = pcdcodec.encode(path, tmp_path / "rest.pcdc", exclude_topics="/k4a/ir")
    assert summary.frames == 3
    assert [s["name"] for s in summary.left_out] == ["IR"]


def test_a_rig_of_camera_files_names_the_tracks_it_does_not_keep(tmp_path: Path) -> None:
    from pcdcodec.recording import encode_rig

    paths = [tmp_path / "a.mkv", tmp_path / "b.mkv"]
    for p in paths:
        _k4a_mkv(p, 2)
    summary = encode_rig(paths, tmp_path / "rig.pcdc")
    for p in paths:  # a rig keeps no other topics: each file's are named, not lost unseen
        assert [s["name"] for s in summary.left_out[str(p)]] == ["IMU", "IR", "notes.txt"]


def test_decode_writes_the_ir_as_16_bit_png_files_bit_exact(tmp_path: Path) -> None:
    import imagecodecs

    path = tmp_path / "ir.mkv"
    held = _k4a_mkv(path, 3)
    rec = tmp_path / "ir.pcdc"
    pcdcodec.encode(path, rec)
    out = tmp_path / "decoded"
    text = _cli("decode", str(rec), "-o", str(out))
    assert "kept images  /k4a/ir: 3 16-bit PNG files in k4a/ir/" in text
    listed = (out / "k4a" / "ir.txt").read_text().splitlines()[2:]
    depth_times = [line.split()[0] for line in (out / "depth.txt").read_text().splitlines()[2:]]
    assert [line.split()[0] for line in listed] == depth_times  # each at its capture's time
    for line, want in zip(listed, held["ir"], strict=True):
        got = imagecodecs.png_decode((out / line.split()[1]).read_bytes())
        assert got.dtype == np.uint16
        assert np.array_equal(got, want)
