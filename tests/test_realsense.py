"""The librealsense .bag reader, on a real D435 recording (skipped when the data is absent)."""

from __future__ import annotations

import itertools
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import InputError, PcdcodecError
from pcdcodec.sources.realsense import RealSenseBagSource

from .conftest import SHARED_DATA

BAG = SHARED_DATA / "bags" / "realsense" / "single_depth_color_640x480.bag"
needs_bag = pytest.mark.skipif(not BAG.exists(), reason=f"{BAG} is not present")

# What librealsense itself (pyrealsense2 2.59 playback of this bag) reports: the depth-to-color
# extrinsic (rotation column-major), and CRC-32s of the depth and color of its frameset, which
# is our second frame. Its rs2::align to color fills 300,874 pixels summing to 405,735,239.
RS_ROTATION = [
    0.99986332654953,
    0.01030866801738739,
    -0.01292696874588728,
    -0.010310042649507523,
    0.9999468326568604,
    -3.9757887861924246e-05,
    0.012925871647894382,
    0.00017303005733992904,
    0.9999164342880249,
]
RS_TRANSLATION = [0.014311314560472965, 0.000602306448854506, 0.000610804243478924]
RS_DEPTH_CRC, RS_COLOR_CRC = 1410488731, 444443446
RS_ALIGNED_PIXELS, RS_ALIGNED_SUM = 300_874, 405_735_239


@needs_bag
def test_open_source_picks_the_realsense_reader() -> None:
    with pcdcodec.open_source(BAG) as src:
        assert isinstance(src, RealSenseBagSource)
        assert src.depth_scale == 1000.0
        assert src.metadata["device"] == "Intel RealSense D435"
        assert src.metadata["serial"] == "728612070259"
        assert src.intrinsics is not None
        assert src.intrinsics.shape == (480, 640)
        assert src.intrinsics.fx == pytest.approx(390.43145752)
        assert src.color_intrinsics is not None
        assert src.color_intrinsics.fx == pytest.approx(613.20367432)
        rotation = np.reshape(RS_ROTATION, (3, 3)).T  # librealsense stores it column-major
        np.testing.assert_allclose(src.depth_to_color[:3, :3], rotation, atol=1e-7)
        np.testing.assert_allclose(src.depth_to_color[:3, 3], RS_TRANSLATION, atol=1e-7)
        with pytest.raises(TypeError):
            len(src)  # how many depth frames find a color frame is known by pairing them
        # The one color frame is 101 ms from the first depth frame and 268 ms from the second:
        # within the default 20 ms neither pairs, and all three images are reported dropped.
        assert list(src) == []
        assert src.dropped == {"color": 1, "depth": 2}
    # With a wider tolerance, the nearer depth frame takes the color frame, once; the depth
    # frame 268 ms away is dropped and reported, not given a color taken 268 ms earlier.
    with RealSenseBagSource(BAG, max_difference=150_000_000) as wide:
        frames = list(wide)
        assert wide.dropped == {"color": 0, "depth": 1}
    assert [f.timestamp_ns for f in frames] == [360_815_089_000]
    assert zlib.crc32(frames[0].color.tobytes()) == RS_COLOR_CRC
    assert zlib.crc32(_depth_frames()[1].depth.tobytes()) == RS_DEPTH_CRC
    with RealSenseBagSource(BAG, max_dt=0.3) as former:  # max_dt: the former name, in seconds
        assert former.max_difference == 300_000_000
        assert [f.timestamp_ns for f in former] == [360_815_089_000]


def _depth_frames() -> list[Any]:
    """The depth frames of the real bag (read as a plain ROS 1 bag, depth only)."""
    with pcdcodec.open_source(BAG, kind="rosbag", color_topic="") as src:
        return list(src)


@needs_bag
def test_real_bag_encode_reports_the_depth_without_a_color_frame(tmp_path: Path) -> None:
    summary = pcdcodec.encode(BAG, tmp_path / "rs.pcdc", color="ffv1", max_difference=150_000_000)
    assert summary.frames == 1
    assert summary.dropped == {"color": 0, "depth": 1}
    with pytest.raises(InputError, match="every image was dropped for lack of a partner"):
        pcdcodec.encode(BAG, tmp_path / "none.pcdc", color="ffv1")
    assert not (tmp_path / "none.pcdc").exists()


@needs_bag
def test_registration_close_to_librealsense_align() -> None:
    frame = _depth_frames()[1]
    with pcdcodec.open_source(BAG) as src:
        proj = pcdcodec.Projector(
            src.intrinsics,
            src.depth_scale,
            color_intrinsics=src.color_intrinsics,
            depth_to_color=src.depth_to_color,
        )
    aligned = proj.register_depth(frame.depth, footprint=True, values="depth")
    filled = int((aligned > 0).sum())
    assert abs(filled - RS_ALIGNED_PIXELS) < 0.002 * RS_ALIGNED_PIXELS
    assert abs(int(aligned.sum(dtype=np.int64)) - RS_ALIGNED_SUM) < 0.002 * RS_ALIGNED_SUM


@needs_bag
def test_recording_keeps_both_cameras_and_exact_depth(tmp_path: Path) -> None:
    out = tmp_path / "rs.pcdc"
    with pcdcodec.open_source(BAG, max_difference=150_000_000) as src:
        frames = list(src)
        with pcdcodec.open(
            out,
            "w",
            intrinsics=src.intrinsics,
            depth_scale=src.depth_scale,
            color="ffv1",
            color_intrinsics=src.color_intrinsics,
            depth_to_color=src.depth_to_color,
            metadata=src.metadata,
        ) as rec:
            rec.write_frames(frames)
    with pcdcodec.open(out) as rec:
        assert rec.format_version == 2
        assert rec.metadata["serial"] == "728612070259"
        for got, want in zip(rec, frames, strict=True):
            assert np.array_equal(got.depth, want.depth)
            assert np.array_equal(got.color, want.color)
        points, colors = rec[0].to_points()
        assert colors is not None
        assert points.shape[0] == int((frames[0].depth > 0).sum())


def _copy_without(src: Path, dst: Path, drop: str) -> None:
    from rosbags.rosbag1 import Reader, Writer

    with Reader(src) as reader, Writer(dst) as writer:
        conns = {}
        for c in reader.connections:
            if drop in c.topic:
                continue
            conns[c.id] = writer.add_connection(
                c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest
            )
        for c, t, raw in reader.messages():
            if c.id in conns:
                writer.write(conns[c.id], t, raw)


@needs_bag
def test_bag_without_depth_units(tmp_path: Path) -> None:
    broken = tmp_path / "no_units.bag"
    _copy_without(BAG, broken, "Depth Units")
    with pytest.raises(InputError, match=r"no depth units.*Depth Units/value.*depth_scale="):
        pcdcodec.open_source(broken)
    with pcdcodec.open_source(broken, depth_scale=1000.0) as src:
        assert src.depth_scale == 1000.0
    no_tf = tmp_path / "no_tf.bag"
    _copy_without(BAG, no_tf, "Color_0/tf")
    with pytest.raises(InputError, match="no extrinsic for /device_0/sensor_1/Color_0"):
        pcdcodec.open_source(no_tf)


@needs_bag
def test_exported_bag_gives_each_camera_its_own_info(tmp_path: Path) -> None:
    """A two-camera recording exported as a bag: the color CameraInfo is the color camera's
    (not the depth camera's), and the colored cloud is made through the color camera."""
    from rosbags.highlevel import AnyReader

    rec_path = tmp_path / "rs.pcdc"
    with pcdcodec.open_source(BAG, max_difference=150_000_000) as src:
        depth_cam, color_cam = src.intrinsics, src.color_intrinsics
        assert depth_cam is not None
        assert color_cam is not None
        pcdcodec.encode(src, rec_path, color="ffv1")
    bag = tmp_path / "rs-out.bag"
    pcdcodec.export_bag(rec_path, bag, to="rosbag1", cloud=True, kept=False)
    infos: dict[str, list[float]] = {}
    clouds = 0
    with AnyReader([bag]) as reader:
        for conn, _, raw in reader.messages():
            if conn.topic.endswith("camera_info"):
                msg = reader.deserialize(raw, conn.msgtype)
                infos[conn.topic] = [float(v) for v in msg.K]
            elif conn.msgtype.endswith("PointCloud2"):
                clouds += 1
    assert infos["/camera/depth/camera_info"] == [float(v) for v in depth_cam.K.ravel()]
    assert infos["/camera/color/camera_info"] == [float(v) for v in color_cam.K.ravel()]
    assert infos["/camera/color/camera_info"] != infos["/camera/depth/camera_info"]
    assert clouds == 1


# -- small RealSense-style bags, built with librealsense's topics (tests/camera_file_fuzz.py) --


def _bag(tmp_path: Path, change: Any = None, **options: Any) -> Path:
    """A 3-frame bag (depth 8x6 mono16, color 10x8 rgb8), ``change(spec)`` applied first."""
    from .camera_file_fuzz import rs_spec, write_bag

    spec = rs_spec(**options)
    if change is not None:
        change(spec)
    path = tmp_path / "small.bag"
    write_bag(spec, path)
    return path


def _image(spec: Any, kind: str, k: int = 0) -> Any:
    return [r for r in spec.records if r.topic.endswith(f"{kind}_0/image/data")][k].msg


def test_small_bag_reads_exactly(tmp_path: Path) -> None:
    from .camera_file_fuzz import rs_spec

    spec = rs_spec()
    with RealSenseBagSource(_bag(tmp_path)) as src:
        frames = list(src)
    assert len(frames) == 3
    for k, f in enumerate(frames):
        depth, color = _image(spec, "Depth", k), _image(spec, "Color", k)
        assert np.array_equal(f.depth, np.asarray(depth.data).view("<u2").reshape(6, 8))
        assert np.array_equal(f.color, np.asarray(color.data).reshape(8, 10, 3))


def _set(kind: str, k: int = 1, **fields: Any) -> Any:
    def change(spec: Any) -> None:
        for key, value in fields.items():
            setattr(_image(spec, kind, k), key, value)

    return change


def _read_error(path: Path, match: str) -> str:
    with pytest.raises(PcdcodecError, match=match) as info, pcdcodec.open_source(path) as src:
        list(src)
    assert str(path) in str(info.value)
    return str(info.value)


@pytest.mark.parametrize(
    ("kind", "fields", "match"),
    [
        ("Depth", {"step": 2}, r"step 2 bytes; expected at least 16"),  # was ValueError
        ("Depth", {"step": 7}, r"step 7 bytes; expected at least 16"),  # was ValueError
        ("Depth", {"width": 9}, r"image is 9x6, but its camera info says 8x6"),
        ("Depth", {"height": 5}, r"image is 8x5, but its camera info says 8x6"),
        ("Color", {"height": 7}, r"image is 10x7, but its camera info says 10x8"),  # wrong color
        ("Depth", {"encoding": "rgb8"}, r"depth image has encoding 'rgb8'; expected mono16"),
        ("Color", {"encoding": "rgba8"}, r"step 30 bytes; expected at least 40"),
        ("Color", {"encoding": "yuv422"}, r"color image has encoding 'yuv422'.*rgb8, bgr8"),
        ("Depth", {"data": np.zeros(95, np.uint8)}, r"holds 95 bytes; expected height 6 x step"),
    ],
)
def test_image_layout_is_checked_against_its_camera(
    tmp_path: Path, kind: str, fields: dict[str, Any], match: str
) -> None:
    message = _read_error(_bag(tmp_path, _set(kind, **fields)), match)
    assert f"{kind}_0/image/data at " in message  # the topic and the stamp


def test_padded_rows_read_the_same_pixels(tmp_path: Path) -> None:
    def pad(spec: Any) -> None:
        msg = _image(spec, "Depth", 1)
        rows = np.asarray(msg.data).reshape(6, 16)
        msg.data = np.concatenate([rows, np.full((6, 4), 255, np.uint8)], axis=1).reshape(-1)
        msg.step = 20

    padded = tmp_path / "padded"
    padded.mkdir()
    with RealSenseBagSource(_bag(tmp_path)) as a, RealSenseBagSource(_bag(padded, pad)) as b:
        for x, y in zip(a, b, strict=True):
            assert np.array_equal(x.depth, y.depth)


def test_lz4_chunk_damage_is_an_error_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A byte changed inside an lz4 chunk: rosbags raises RuntimeError (LZ4F_decompress
    failed) or AssertionError; the reader and ``pcdcodec info`` say what is wrong instead."""
    from pcdcodec.cli import main

    from .camera_file_fuzz import _bag_regions

    path = _bag(tmp_path)
    data = bytearray(path.read_bytes())
    regions = _bag_regions(bytes(data))
    chunks = [
        data_span
        for head, data_span in itertools.pairwise(regions)
        if b"compression=lz4" in data[head[0] : head[1]]
    ]
    data[chunks[0][0] + 70] ^= 0x5A  # rosbags: LZ4F_decompress failed
    bad = tmp_path / "bad.bag"
    bad.write_bytes(bytes(data))
    _read_error(bad, "the bag is damaged")
    assert main(["info", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert str(bad) in err


def test_stamp_nanoseconds_out_of_range(tmp_path: Path) -> None:
    def change(spec: Any) -> None:
        _image(spec, "Depth", 1).header.stamp.nanosec = 1_500_000_000

    _read_error(_bag(tmp_path, change), r"nanoseconds 1500000000; expected 0 to 999999999")


@pytest.mark.parametrize("units", [float("inf"), -float("inf")])
def test_depth_units_must_give_a_finite_scale(tmp_path: Path, units: float) -> None:
    def change(spec: Any) -> None:
        next(r for r in spec.records if "Depth Units" in r.topic).msg.data = units

    with pytest.raises(InputError, match=r"records Depth Units .*finite") as info:
        RealSenseBagSource(_bag(tmp_path, change))
    assert str(tmp_path) in str(info.value)


def test_zero_quaternion_names_the_file(tmp_path: Path) -> None:
    def change(spec: Any) -> None:
        rotation = next(r for r in spec.records if r.topic.endswith("Color_0/tf/0")).msg.rotation
        rotation.w = 0.0

    with pytest.raises(InputError, match=r"Color_0/tf/0: quaternion .* zero length") as info:
        RealSenseBagSource(_bag(tmp_path, change))
    assert str(tmp_path) in str(info.value)


def test_topic_of_another_type_is_refused(tmp_path: Path) -> None:
    from .camera_file_fuzz import rs_spec, write_bag

    path = tmp_path / "typed.bag"
    units = "/device_0/sensor_0/option/Depth Units/value"
    write_bag(rs_spec(), path, {units: "sensor_msgs/msg/CameraInfo"})  # was SerdeError
    with pytest.raises(InputError, match=r"holds sensor_msgs/msg/CameraInfo; expected .*Float32"):
        RealSenseBagSource(path)


def test_mjpeg_color_is_checked_and_decoded(tmp_path: Path) -> None:
    import cv2

    from .camera_file_fuzz import rs_spec

    spec = rs_spec(color_encoding="mjpeg")
    path = _bag(tmp_path, color_encoding="mjpeg")
    with RealSenseBagSource(path) as src:
        frames = list(src)
    assert len(frames) == 3
    for k, f in enumerate(frames):
        jpeg = np.asarray(_image(spec, "Color", k).data)
        want = cv2.imdecode(jpeg, cv2.IMREAD_COLOR)[..., ::-1]
        assert np.array_equal(f.color, want)

    def cut(spec: Any) -> None:
        msg = _image(spec, "Color", 1)
        msg.data = np.asarray(msg.data)[: len(msg.data) // 2].copy()

    cut_dir = tmp_path / "cut"
    cut_dir.mkdir()
    _read_error(_bag(cut_dir, cut, color_encoding="mjpeg"), r"Color_0/image/data at .*cut short")


def test_depth_frames_without_color_are_counted(tmp_path: Path) -> None:
    """Depth and color pair by the rule of every reader (within ``max_difference``, each image
    once): the images left without a partner are counted, as the bag readers count theirs, and
    in the encode summary."""

    def change(spec: Any) -> None:
        _image(spec, "Color", 2).header.stamp.sec = 5  # 4 s after its depth frame

    path = _bag(tmp_path, change)
    with RealSenseBagSource(path, max_difference=10_000_000) as src:
        assert len(list(src)) == 2
        assert src.dropped == {"color": 1, "depth": 1}
    summary = pcdcodec.encode(path, tmp_path / "out.pcdc", color="ffv1")
    assert summary.frames == 2
    assert summary.dropped == {"color": 1, "depth": 1}


def test_stamps_after_2_to_the_31_seconds_read_one_way(tmp_path: Path) -> None:
    """ROS 1 seconds are unsigned: a stamp at or after 2^31 s gives the same timestamps when
    iterating as through the frame index (rosbags reads the seconds as signed)."""

    def change(spec: Any) -> None:
        for r in spec.records:
            if r.topic.endswith("/image/data"):
                r.msg.header.stamp.sec = -(2**31) + 100  # the bytes of 2^31 + 100 unsigned

    with RealSenseBagSource(_bag(tmp_path, change)) as src:
        stamps = [f.timestamp_ns for f in src]
        index = src.frame_index()
        late = [f.timestamp_ns for f in src.frames(1)]
    assert stamps[0] == (2**31 + 100) * 10**9 + 0
    assert stamps == [int(t) for t in index.timestamps]
    assert late == stamps[1:]


def _index_redirected(tmp_path: Path) -> Path:
    """The small bag with the depth topic's first index record filed under connection 2053,
    which the bag does not have (one damaged byte of the record's ``conn`` field)."""
    import struct

    from rosbags.rosbag1 import Reader

    path = _bag(tmp_path, compression="")
    with Reader(path) as reader:
        depth = next(c.id for c in reader.connections if c.topic.endswith("Depth_0/image/data"))
    data = bytearray(path.read_bytes())
    field = b"op=\x04" + b"\x08\x00\x00\x00ver=\x01\x00\x00\x00\t\x00\x00\x00conn="
    at = data.index(field + struct.pack("<I", depth)) + len(field)
    data[at + 1] = 8
    bad = tmp_path / "redirected.bag"
    bad.write_bytes(bytes(data))
    return bad


def test_index_record_of_an_unknown_connection_is_damage_not_fewer_frames(
    tmp_path: Path,
) -> None:
    # rosbags drops the record's messages without a word: 1 of 3 frames was read, none dropped.
    bad = _index_redirected(tmp_path)
    with (
        pytest.raises(PcdcodecError, match=r"index is damaged.*Depth_0/image/data") as info,
        pcdcodec.open_source(bad) as src,
    ):
        list(src)
    assert str(bad) in str(info.value)


def test_index_record_of_an_unknown_connection_in_a_plain_ros1_bag(tmp_path: Path) -> None:
    from pcdcodec.sources.rosbag import RosbagSource

    bad = _index_redirected(tmp_path)
    cam = pcdcodec.CameraIntrinsics(8, 6, 4.0, 4.0, 4.0, 3.0)
    topic = "/device_0/sensor_0/Depth_0/image/data"
    with (
        pytest.raises(PcdcodecError, match=r"index is damaged.*Depth_0/image/data") as info,
        RosbagSource(bad, depth_topic=topic, color_topic="", intrinsics=cam, depth_scale=1000),
    ):
        pass
    assert str(bad) in str(info.value)
