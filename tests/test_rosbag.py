"""ROS 1 and ROS 2 bags in and out: the real Spot and RealSense bags, PointCloud2 bags written from
the real sequences, every image encoding, and bad input."""

from __future__ import annotations

import shutil
import struct
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.errors import DecodeError, InputError, PcdcodecError
from pcdcodec.ros import messages as rm
from pcdcodec.sources.base import detect_kind

from .conftest import SHARED_DATA, load_colors, load_depths, to_metres

BAGS = SHARED_DATA / "bags"
SPOT = BAGS / "spot"
ROS2 = BAGS / "ros2-converted"
RS_BAG = BAGS / "realsense" / "single_depth_color_640x480.bag"
SPOT_DEPTH = "/spot/depth/frontleft/image"

DEPTH_TOPIC = "/cam/depth/image_raw"

needs_bags = pytest.mark.skipif(not SPOT.is_dir(), reason=f"{SPOT} is not present")

NS = 1_000_000_000


# -- writing arbitrary bags -------------------------------------------------------------------


def _store(ros2: bool) -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)


def _header(store: Any, ros2: bool, ns: int, frame_id: str = "cam") -> Any:
    t = store.types
    stamp = t["builtin_interfaces/msg/Time"](sec=ns // NS, nanosec=ns % NS)
    if ros2:
        return t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
    return t["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame_id)


def _image(
    store: Any, ros2: bool, ns: int, arr: Any, enc: str, big: bool = False, pad: int = 0
) -> Any:
    h, w = arr.shape[:2]
    a = np.ascontiguousarray(arr)
    if big:
        a = a.astype(a.dtype.newbyteorder(">"))
    rows = a.reshape(h, -1).view(np.uint8)
    if pad:
        rows = np.concatenate([rows, np.full((h, pad), 0xAB, np.uint8)], axis=1)
    return store.types["sensor_msgs/msg/Image"](
        header=_header(store, ros2, ns), height=h, width=w, encoding=enc,
        is_bigendian=int(big), step=rows.shape[1], data=rows.reshape(-1),
    )  # fmt: skip


def _info(store: Any, ros2: bool, ns: int, w: int, h: int, f: float = 300.0) -> Any:
    t = store.types
    k = np.array([f, 0, w / 2, 0, f, h / 2, 0, 0, 1], np.float64)
    r = np.eye(3).reshape(-1)
    p = np.array([f, 0, w / 2, 0, 0, f, h / 2, 0, 0, 0, 1, 0], np.float64)
    d = np.array([0.1, 0.0, 0.0, 0.0, 0.0])
    roi = t["sensor_msgs/msg/RegionOfInterest"](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    arrays = {"d": d, "k": k, "r": r, "p": p}
    if not ros2:
        arrays = {key.upper(): v for key, v in arrays.items()}
    return t["sensor_msgs/msg/CameraInfo"](
        header=_header(store, ros2, ns), height=h, width=w, distortion_model="plumb_bob",
        binning_x=0, binning_y=0, roi=roi, **arrays,
    )  # fmt: skip


def write_bag(
    path: Path, messages: list[tuple[str, int, Any]], *, ros2: bool = False, store: Any = None
) -> Path:
    """Write ``(topic, log time ns, message)`` triples into a ROS 1 bag or a ROS 2 mcap bag."""
    store = store or _store(ros2)
    if ros2:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer: Any = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    else:
        from rosbags.rosbag1 import Writer as Writer1

        writer = Writer1(path)
    conns: dict[str, Any] = {}
    with writer:
        for topic, ns, msg in messages:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msg.__msgtype__, typestore=store)
            ser = store.serialize_cdr if ros2 else store.serialize_ros1
            writer.write(conns[topic], ns, bytes(ser(msg, msg.__msgtype__)))
    return path


def _small(n: int = 3, step: int = 4) -> list[tuple[Any, Any]]:
    """The first frames of the bundled sample, downscaled by ``step`` (160x120)."""
    seq = pcdcodec.load_sample(max_frames=n)
    return [(f.color[::step, ::step].copy(), f.depth[::step, ::step].copy()) for f in seq]


# -- probing ----------------------------------------------------------------------------------


@needs_bags
def test_open_source_picks_bags_by_content_not_name(tmp_path: Path) -> None:
    renamed = tmp_path / "recording.dat"
    shutil.copy(SPOT / "compressedDepth.bag", renamed)
    assert detect_kind(renamed) == "rosbag"
    assert detect_kind(ROS2 / "spot_ros2_mcap") == "rosbag"
    assert detect_kind(ROS2 / "spot_ros2_sqlite" / "spot_ros2_sqlite.db3") == "rosbag"
    mcap_renamed = tmp_path / "x.bin"
    shutil.copy(ROS2 / "spot_ros2_mcap" / "spot_ros2_mcap.mcap", mcap_renamed)
    assert detect_kind(mcap_renamed) == "rosbag"
    with pcdcodec.open_source(mcap_renamed) as src:
        assert len(list(src)) == 1
    # A .pcdc recording is MCAP too, but with pcdcodec's profile: not a bag, a recording.
    rec = tmp_path / "r.pcdc"
    seq = pcdcodec.load_sample(max_frames=1)
    with pcdcodec.open(rec, "w", intrinsics=seq.intrinsics, depth_scale=5000.0) as w:
        w.write_frames(seq)
    assert detect_kind(rec) == "recording"
    assert detect_kind(pcdcodec.datasets.sample_dir()) == "folder"


# -- the real Spot bags: depth and color, every transport, ROS 1 and ROS 2 ----------------------


def _depth_of(path: Path, **options: Any) -> np.ndarray[Any, Any]:
    with pcdcodec.open_source(path, color_topic="", **options) as src:
        frames = list(src)
    assert len(frames) == 1
    return frames[0].depth


@needs_bags
def test_spot_compressed_depth_decodes_to_the_raw_frame() -> None:
    truth = _depth_of(SPOT / "raw.bag")
    assert truth.dtype == np.uint16
    assert truth.shape == (240, 424)
    assert 0.5 < np.count_nonzero(truth) / truth.size < 0.8
    # "16UC1; png compressed " (trailing space) and the old "16UC1; compressedDepth" whose
    # header holds garbage depth parameters.
    assert np.array_equal(_depth_of(SPOT / "compressed.bag"), truth)
    assert np.array_equal(_depth_of(SPOT / "compressedDepth.bag"), truth)
    for bag in ("spot_ros2_sqlite", "spot_ros2_mcap"):
        for topic in ("", "/compressed", "/compressedDepth"):
            got = _depth_of(ROS2 / bag, depth_topic=SPOT_DEPTH + topic)
            assert np.array_equal(got, truth), (bag, topic)


@needs_bags
def test_spot_color_rgb8_jpeg_and_mono8() -> None:
    with pcdcodec.open_source(SPOT / "raw.bag") as src:
        raw = src._reader
        conn = next(c for c in raw.connections if c.topic == "/spot/camera/hand_color/image")
        rgb = rm.decode_image(src._first(conn), "color", conn.topic)
        mono_conn = next(c for c in raw.connections if c.topic == "/spot/camera/frontleft/image")
        mono = rm.decode_image(src._first(mono_conn), "color", mono_conn.topic)
    with pcdcodec.open_source(SPOT / "compressed.bag") as src:
        raw = src._reader
        conn = next(c for c in raw.connections if c.topic.startswith("/spot/camera/hand_color"))
        jpeg = rm.decode_compressed(src._first(conn), "color", conn.topic)
    assert rgb.shape == jpeg.shape == (480, 640, 3)
    # "rgb8; jpeg compressed bgr8": the JPEG decodes to the same colors, not swapped channels.
    assert pcdcodec.metrics.psnr(rgb, jpeg) > 30
    assert pcdcodec.metrics.psnr(rgb, jpeg[..., ::-1]) < pcdcodec.metrics.psnr(rgb, jpeg) - 3
    assert mono.shape == (480, 640, 3)
    assert np.array_equal(mono[..., 0], mono[..., 2])


@needs_bags
def test_spot_auto_choice_is_depth_only_and_info_lists_every_topic() -> None:
    with pcdcodec.open_source(SPOT / "raw.bag") as src:
        assert src.depth_topic == SPOT_DEPTH
        assert src.color_topic is None  # no color image of the depth's size
        roles = {c.topic: c.role for c in src.candidates()}
    assert roles[SPOT_DEPTH] == "depth"
    assert roles["/spot/camera/hand_color/image"] == "color"
    from pcdcodec.cli import main

    assert main(["info", str(SPOT / "raw.bag")]) == 0


@needs_bags
def test_realsense_bag_read_as_a_generic_ros1_bag(tmp_path: Path) -> None:
    from pcdcodec.sources.rosbag import RosbagSource

    with RosbagSource(RS_BAG, color_topic="") as src:
        assert src.depth_topic == "/device_0/sensor_0/Depth_0/image/data"
        assert src.info_topic == "/device_0/sensor_0/Depth_0/info/camera_info"
        assert src.intrinsics is not None
        assert src.intrinsics.shape == (480, 640)
        frames = list(src)
    assert [f.depth.dtype for f in frames] == [np.uint16, np.uint16]
    assert all(f.color is None for f in frames)
    with RosbagSource(ROS2 / "rs_ros2_mcap", color_topic="") as src2:
        frames2 = list(src2)
    for a, b in zip(frames, frames2, strict=True):
        assert np.array_equal(a.depth, b.depth)
        assert a.timestamp_ns == b.timestamp_ns
    # Color and depth come from different sensors (the color topic's CameraInfo is not the
    # depth's) and the bag has no tf: refused rather than recorded as registered.
    with pytest.raises(InputError, match=r"camera apart from the depth.*pass depth_to_color="):
        pcdcodec.encode(RS_BAG, tmp_path / "x.pcdc", kind="rosbag")
    # With the transform given, the images are 100 ms apart: nothing pairs, and encode says so.
    with pytest.raises(InputError, match="dropped for lack of a partner"):
        pcdcodec.encode(RS_BAG, tmp_path / "x.pcdc", kind="rosbag", depth_to_color=np.eye(4))
    assert not (tmp_path / "x.pcdc").exists()


@needs_bags
@pytest.mark.parametrize("to", ["rosbag1", "rosbag2"])
def test_round_trip_bag_to_pcdc_to_bag_is_bit_exact(tmp_path: Path, to: str) -> None:
    summary = pcdcodec.encode(RS_BAG, tmp_path / "rs.pcdc", kind="rosbag", color_topic="")
    assert summary.frames == 2
    with pcdcodec.open_source(RS_BAG, kind="rosbag", color_topic="") as src:
        original = list(src)
    out = tmp_path / ("back.bag" if to == "rosbag1" else "back")
    for compressed in (False, True):
        if out.exists():
            shutil.rmtree(out) if out.is_dir() else out.unlink()
        # The camera alone (kept=False): the bag's other topics are tests/test_bag_export.py's.
        pcdcodec.export_bag(
            tmp_path / "rs.pcdc", out, to=to, compressed_depth=compressed, kept=False
        )
        with pcdcodec.open_source(out) as back:
            assert back.info_topic == "/camera/depth/camera_info"
            assert back.intrinsics == summary_intrinsics(tmp_path / "rs.pcdc")
            frames = list(back)
        assert [f.timestamp_ns for f in frames] == [f.timestamp_ns for f in original]
        for a, b in zip(frames, original, strict=True):
            assert a.depth.dtype == np.uint16
            assert np.array_equal(a.depth, b.depth)


def summary_intrinsics(path: Path) -> Any:
    with pcdcodec.open(path) as rec:
        return rec.intrinsics


# -- every encoding, both byte orders, padded rows ---------------------------------------------


@pytest.mark.parametrize("ros2", [False, True])
def test_image_encodings_and_padding(tmp_path: Path, ros2: bool) -> None:
    store = _store(ros2)
    color, depth = _small(1)[0]
    h, w = depth.shape
    metres = to_metres(depth, 5000.0)
    cases = [
        ("16UC1", depth, False, 0, depth),
        ("mono16", depth, True, 6, depth),  # big-endian, padded rows
        ("32FC1", metres, True, 4, metres),
        ("32FC1", metres, False, 0, metres),
    ]
    for i, (enc, arr, big, pad, expect) in enumerate(cases):
        bag = tmp_path / f"d{i}{'' if ros2 else '.bag'}"
        msgs = [
            (
                "/cam/depth/image",
                1 + k,
                _image(store, ros2, NS + k * 33_000_000, arr, enc, big, pad),
            )
            for k in range(2)
        ]
        write_bag(bag, msgs, ros2=ros2)
        with pcdcodec.open_source(bag) as src:
            assert src.depth_scale == (1.0 if enc == "32FC1" else 1000.0)
            got = [f.depth for f in src]
        assert len(got) == 2
        assert got[0].dtype == expect.dtype
        assert np.array_equal(got[0], expect, equal_nan=True), enc
    color_cases = {
        "rgb8": color,
        "bgr8": color[..., ::-1],
        "rgba8": np.dstack([color, np.full((h, w), 7, np.uint8)]),
        "bgra8": np.dstack([color[..., ::-1], np.full((h, w), 7, np.uint8)]),
        "mono8": color[..., 1],
    }
    for enc, arr in color_cases.items():
        msg = _image(store, ros2, NS, arr, enc, pad=3)
        got = rm.decode_image(msg, "color", "/c")
        want = np.repeat(color[..., 1:2], 3, axis=2) if enc == "mono8" else color
        assert np.array_equal(got, want), enc


@needs_bags
def test_compressed_depth_png_and_rvl_with_old_and_new_format_strings(tmp_path: Path) -> None:
    import rvl

    truth = _depth_of(SPOT / "raw.bag")
    h, w = truth.shape
    garbage = struct.pack("<iff", 0, 123.5, -7.25)  # ignored for 16-bit depth
    # An independent coder (its output starts with the pixel count, which ROS does not write).
    rvl_body = struct.pack("<II", w, h) + rvl.compress(truth.tobytes())[4:]
    png = rm.compressed_depth_encode(truth)[12:]
    store = _store(False)
    cases = {
        "16UC1; compressedDepth": garbage + png,
        "16UC1; compressedDepth png": garbage + png,
        "16UC1; compressedDepth rvl": garbage + rvl_body,
        "mono16; compressedDepth rvl": rm.compressed_depth_encode(truth, rvl=True),
    }
    for fmt, data in cases.items():
        msg = store.types["sensor_msgs/msg/CompressedImage"](
            header=_header(store, False, NS), format=fmt, data=np.frombuffer(data, np.uint8)
        )
        assert rm.compressed_kind(fmt) == "depth"
        assert np.array_equal(rm.decode_compressed(msg, "depth", "/d"), truth), fmt
    # Our RVL payload is byte for byte what the independent coder writes.
    assert rm.compressed_depth_encode(truth, rvl=True)[20:] == rvl.compress(truth.tobytes())[4:]
    bad = store.types["sensor_msgs/msg/CompressedImage"](
        header=_header(store, False, NS),
        format="16UC1; compressedDepth png",
        data=np.frombuffer(garbage + b"JUNKJUNKJUNK", np.uint8),
    )
    with pytest.raises(DecodeError, match="byte offset 12"):
        rm.decode_compressed(bad, "depth", "/d")


# -- PointCloud2: fields by name, both byte orders, rgb and rgba -------------------------------


def _cloud_msg(pts: Any, fields: list[tuple[str, int, int]], big: bool, row_pad: int = 0) -> Any:
    h, w = pts.shape
    raw = pts.reshape(-1).view(np.uint8).reshape(h, w * pts.dtype.itemsize)
    if row_pad:
        raw = np.concatenate([raw, np.zeros((h, row_pad), np.uint8)], axis=1)
    return SimpleNamespace(
        height=h, width=w, is_bigendian=big, point_step=pts.dtype.itemsize,
        row_step=raw.shape[1], data=raw.reshape(-1),
        fields=[SimpleNamespace(name=n, offset=o, datatype=d, count=1) for n, o, d in fields],
    )  # fmt: skip


@pytest.mark.parametrize("big", [False, True])
@pytest.mark.parametrize("color_field", ["rgb", "rgba"])
@pytest.mark.parametrize("color_type", [7, 6])
def test_cloud_fields_by_name_offset_and_type(big: bool, color_field: str, color_type: int) -> None:
    color, depth = _small(1)[0]
    intr = pcdcodec.CameraIntrinsics(160, 120, 131.25, 131.25, 79.875, 59.875)
    xyz = pcdcodec.Projector(intr, depth_scale=5000.0).to_organized(depth)
    o = ">" if big else "<"
    # Fields in an unusual order: color first, then z, x, y; a 24-byte point.
    dt = np.dtype(
        {
            "names": [color_field, "z", "x", "y"],
            "formats": [o + "u4", o + "f4", o + "f4", o + "f4"],
            "offsets": [0, 4, 12, 16],
            "itemsize": 24,
        }
    )
    pts = np.zeros(depth.shape, dt)
    pts["x"], pts["y"], pts["z"] = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    c = color.astype(np.uint32)
    pts[color_field] = (
        (255 << 24) * (color_field == "rgba") | (c[..., 0] << 16) | (c[..., 1] << 8) | c[..., 2]
    )
    fields = [(color_field, 0, color_type), ("z", 4, 7), ("x", 12, 7), ("y", 16, 7)]
    msg = _cloud_msg(pts, fields, big, row_pad=8)
    layout = rm.cloud_layout(msg, "/pts")
    z, rgb, got = rm.cloud_to_rgbd(msg, layout, "/pts")
    assert z.dtype == np.float32
    assert np.array_equal(z.view(np.uint32), xyz[..., 2].view(np.uint32))  # bit-exact, NaN too
    assert np.array_equal(rgb, color)
    fitted, residual = rm.fit_intrinsics(got, "/pts")
    assert residual < 1e-3
    assert abs(fitted.fx - intr.fx) < 1e-3
    assert abs(fitted.cy - intr.cy) < 1e-3


def test_cloud_errors() -> None:
    pts = np.zeros((1, 50), np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")]))
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    with pytest.raises(InputError, match=r"not organized \(height 1"):
        rm.cloud_layout(_cloud_msg(pts, fields, False), "/flat")
    organized = np.zeros((4, 5), pts.dtype)
    with pytest.raises(InputError, match="field 'z' is FLOAT64"):
        rm.cloud_layout(_cloud_msg(organized, [*fields[:2], ("z", 8, 8)], False), "/t")
    with pytest.raises(InputError, match="no 'y' field"):
        rm.cloud_layout(_cloud_msg(organized, [fields[0], fields[2]], False), "/t")
    with pytest.raises(InputError, match="byte offset 10 runs past point_step 12"):
        rm.cloud_layout(_cloud_msg(organized, [*fields[:2], ("z", 10, 7)], False), "/t")


# -- PointCloud2 bags written from the real sequences -------------------------------------------


@pytest.mark.parametrize(("to", "info"), [("rosbag1", True), ("rosbag2", False)])
def test_cloud_bag_round_trip_rebuilds_every_point(tmp_path: Path, to: str, info: bool) -> None:
    """A PointCloud2 bag as a camera driver publishes it, encoded with lossless color: every xyz
    comes back within 1e-6 m and every color exactly, with the camera from CameraInfo or fitted."""
    seq = pcdcodec.load_sample(max_frames=3)
    bag = tmp_path / ("cloud.bag" if to == "rosbag1" else "cloud")
    written = pcdcodec.export_bag(
        pcdcodec.datasets.sample_dir(), bag, to=to, images=False, cloud=True,
        camera_info=info, max_frames=3,
    )  # fmt: skip
    assert written["frames"] == 3
    assert written["bytes"] > 3 * 640 * 480 * 32
    rec_path = tmp_path / "c.pcdc"
    # z of these clouds is depth / 5000 in float32: kept as uint16 units (auto), or as float32.
    cloud_depth = "auto" if info else "float32"
    summary = pcdcodec.encode(bag, rec_path, color="ffv1", cloud_depth=cloud_depth)
    assert summary.frames == 3
    assert summary.source["mode"] == "cloud"
    assert ("intrinsics_fit_residual_px" in summary.source) is not info
    projector = pcdcodec.Projector(seq.intrinsics, depth_scale=seq.depth_scale)
    with pcdcodec.open(rec_path) as rec:
        assert rec.depth_scale == (5000.0 if info else 1.0)
        assert rec[0].depth.dtype == (np.uint16 if info else np.float32)
        for frame, original in zip(rec, seq, strict=True):
            # A cloud is stamped as its depth image (TUM's is 10 to 40 us after the color).
            assert frame.timestamp_ns == original.depth_timestamp_ns
            want = projector.to_organized(original.depth)
            got = rec.projector.to_organized(frame.depth)
            valid = np.isfinite(want[..., 2])
            assert np.array_equal(valid, np.isfinite(got[..., 2]))
            err = np.abs(got[valid] - want[valid]).max()
            assert err <= 1e-6
            assert np.array_equal(frame.color, original.color)


def test_cloud_whose_z_stops_being_whole_units_says_how_to_keep_float32(tmp_path: Path) -> None:
    from pcdcodec.convert.rosbag import CLOUD_DTYPE, cloud_array

    store = _store(False)
    frames = _small(2)
    intr = pcdcodec.CameraIntrinsics(160, 120, 131.25, 131.25, 79.75, 59.75)
    projector = pcdcodec.Projector(intr, depth_scale=1000.0)
    field = store.types["sensor_msgs/msg/PointField"]
    msgs = []
    for k, (c, d) in enumerate(frames):
        pts = cloud_array(projector, d, c)
        if k == 1:
            pts["z"] += np.float32(1e-4)  # no longer whole millimetres
        assert pts.dtype == CLOUD_DTYPE
        msg = store.types["sensor_msgs/msg/PointCloud2"](
            header=_header(store, False, NS + k), height=120, width=160,
            fields=[field(name=n, offset=o, datatype=7, count=1) for n, o in (("x", 0), ("y", 4), ("z", 8), ("rgb", 16))],  # noqa: E501
            is_bigendian=False, point_step=32, row_step=160 * 32,
            data=pts.reshape(-1).view(np.uint8), is_dense=False,
        )  # fmt: skip
        msgs.append(("/cam/points", NS + k, msg))
    bag = write_bag(tmp_path / "z.bag", msgs)
    with pytest.raises(InputError, match=r"not whole 1/1000 m steps.*cloud_depth='float32'"):
        pcdcodec.encode(bag, tmp_path / "z.pcdc", intrinsics=intr)
    summary = pcdcodec.encode(bag, tmp_path / "z.pcdc", intrinsics=intr, cloud_depth="float32")
    assert summary.frames == 2
    with pcdcodec.open(tmp_path / "z.pcdc") as rec:
        z = rec[1].depth
    want = cloud_array(projector, frames[1][1], None)["z"] + np.float32(1e-4)
    assert np.array_equal(z, want, equal_nan=True)


# -- sync ---------------------------------------------------------------------------------------


def test_depth_and_color_pair_by_stamp_and_drops_are_counted(tmp_path: Path) -> None:
    store = _store(False)
    frames = _small(3)
    color, depth = frames[0]
    msgs = [("/cam/depth/camera_info", 1, _info(store, False, NS, 160, 120))]
    for k in range(6):
        ts = NS + k * 33_000_000
        msgs.append(("/cam/depth/image_raw", ts, _image(store, False, ts, depth, "16UC1")))
        if k != 2:  # one color frame missing; the others 4 ms late
            msgs.append(
                (
                    "/cam/color/image_raw",
                    ts + 4_000_000,
                    _image(store, False, ts + 4_000_000, color, "rgb8"),
                )
            )
    msgs.append(("/other/color/image_raw", NS, _image(store, False, NS, color[::2, ::2], "rgb8")))
    msgs.sort(key=lambda m: m[1])
    bag = write_bag(tmp_path / "s.bag", msgs)
    with pcdcodec.open_source(bag) as src:
        assert src.color_topic == "/cam/color/image_raw"
        assert src.info_topic == "/cam/depth/camera_info"
        assert src.metadata["distortion"] == "[0.1, 0.0, 0.0, 0.0, 0.0]"
        got = list(src)
        assert [f.timestamp_ns for f in got] == [NS + k * 33_000_000 for k in (0, 1, 3, 4, 5)]
        assert src.dropped == {"color": 0, "depth": 1}
    summary = pcdcodec.encode(bag, tmp_path / "s.pcdc", color="ffv1")
    assert summary.frames == 5
    assert summary.dropped == {"color": 0, "depth": 1}
    with pcdcodec.open(tmp_path / "s.pcdc") as rec:
        assert rec.metadata["distortion_model"] == "plumb_bob"
        assert rec.metadata["ros_depth_topic"] == "/cam/depth/image_raw"


# -- export: what ROS needs to play the bag ------------------------------------------------------


def test_exported_bags_carry_definitions_hashes_and_valid_mcap(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=2)
    rec_path = tmp_path / "r.pcdc"
    with pcdcodec.open(rec_path, "w", intrinsics=seq.intrinsics, depth_scale=5000.0) as w:
        w.write_frames(seq)
    ros1 = tmp_path / "r.bag"
    pcdcodec.export_bag(rec_path, ros1, cloud=True)
    from rosbags.rosbag1 import Reader as Reader1

    with Reader1(ros1) as r:
        by_topic = {c.topic: c for c in r.connections}
        assert by_topic["/camera/depth/image_raw"].digest == "060021388200f6f0f447d0fcd9c64743"
        assert "uint32 height" in by_topic["/camera/depth/image_raw"].msgdef.data
        assert by_topic["/camera/depth_registered/points"].msgtype == "sensor_msgs/msg/PointCloud2"
        # Five topics per frame, and /tf: the sample's frames carry poses (its groundtruth.txt).
        assert "/tf" in by_topic
        assert r.message_count == 2 * 6
    ros2 = tmp_path / "r2"
    pcdcodec.export_bag(rec_path, ros2, to="rosbag2", storage="mcap")
    mcap_file = next(ros2.glob("*.mcap"))
    from mcap.reader import make_reader

    with mcap_file.open("rb") as f:
        reader = make_reader(f, validate_crcs=True)
        assert reader.get_header().profile == "ros2"
        schemas = {s.name for s in reader.get_summary().schemas.values()}
        count = sum(1 for _ in reader.iter_messages())
    assert "sensor_msgs/msg/Image" in schemas
    assert count == 2 * 5  # four topics and /tf
    meta = (ros2 / "metadata.yaml").read_text()
    assert "RIHS01_" in meta  # the type hash ROS 2 Iron+ checks
    assert "mcap" in meta
    with pcdcodec.open_source(ros2) as src:
        back = list(src)
    # Each image at its own stamp; a bag's frame is at its depth's time.
    assert [f.timestamp_ns for f in back] == [f.depth_timestamp_ns for f in seq]
    assert [f.color_timestamp_ns for f in back] == [f.color_timestamp_ns for f in seq]
    assert src.depth_scale == 1.0  # 5000 per metre is not millimetres: exported as 32FC1
    for f, g in zip(back, seq, strict=True):
        assert np.array_equal(f.depth, to_metres(g.depth, 5000.0), equal_nan=True)
    with pytest.raises(InputError, match="already exists"):
        pcdcodec.export_bag(rec_path, ros2, to="rosbag2")
    with pytest.raises(InputError, match="compressedDepth holds 16UC1"):
        pcdcodec.export_bag(rec_path, tmp_path / "c.bag", compressed_depth=True)
    assert not (tmp_path / "c.bag").exists()
    assert not list(tmp_path.glob(".c.bag*"))
    with pytest.raises(InputError, match="bag format must be one of"):
        pcdcodec.export_bag(rec_path, tmp_path / "x", to="rosbag3")


def _header_stamps(bag: Path) -> dict[str, list[tuple[int, int]]]:
    """Each topic's (log time, header stamp) in bag order, and every message's log time under
    the key ``""``."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[tuple[int, int]]] = {"": []}
    with AnyReader([bag]) as r:
        for conn, t, raw in r.messages():
            out[""].append((t, t))
            msg = r.deserialize(raw, conn.msgtype)
            header = getattr(msg, "header", None)
            if header is None and conn.topic == "/tf":
                header = msg.transforms[0].header
            if header is not None:
                ns = header.stamp.sec * NS + header.stamp.nanosec
                out.setdefault(conn.topic, []).append((t, ns))
    return out


@pytest.mark.parametrize("to", ["rosbag1", "rosbag2"])
def test_export_stamps_each_image_with_its_own_time(tmp_path: Path, to: str) -> None:
    """TUM stamps color and depth apart; the bag's images and camera infos keep each its own."""
    rec_path = tmp_path / "tum.pcdc"
    pcdcodec.encode(pcdcodec.datasets.sample_dir(), rec_path, max_frames=6)
    with pcdcodec.open(rec_path) as r:
        frames = list(r)
    colors = [f.color_timestamp_ns for f in frames]
    depths = [f.depth_timestamp_ns for f in frames]
    assert all(c != d for c, d in zip(colors, depths, strict=True))  # TUM's own stamps
    out = tmp_path / ("tum.bag" if to == "rosbag1" else "tum2")
    pcdcodec.export_bag(rec_path, out, to=to, cloud=True)
    got = _header_stamps(out)
    for topic, want in (
        ("/camera/color/image_raw", colors),
        ("/camera/color/camera_info", colors),
        ("/camera/depth/image_raw", depths),
        ("/camera/depth/camera_info", depths),
    ):
        assert [ns for _, ns in got[topic]] == want, topic
        assert [t for t, _ in got[topic]] == want, topic  # logged at its stamp too
    # The cloud (in the depth camera's pixels) and the pose at the depth's time.
    assert [ns for _, ns in got["/camera/depth_registered/points"]] == depths
    assert [ns for _, ns in got["/tf"]] == depths
    # The bag is in time order.
    logged = [t for t, _ in got[""]]
    assert logged == sorted(logged)
    # Read back, the images pair as they were, each with its own stamp.
    with pcdcodec.open_source(out) as src:
        back = list(src)
    assert len(back) == len(frames)
    for a, b in zip(back, frames, strict=True):
        assert a.depth_timestamp_ns == b.depth_timestamp_ns
        assert a.color_timestamp_ns == b.color_timestamp_ns
        np.testing.assert_array_equal(a.color, b.color)
        np.testing.assert_array_equal(a.depth, to_metres(b.depth, 5000.0))


def test_cli_export_and_encode_a_bag(tmp_path: Path) -> None:
    from pcdcodec.cli import main

    seq = pcdcodec.load_sample(max_frames=2)
    rec_path = tmp_path / "r.pcdc"
    with pcdcodec.open(rec_path, "w", intrinsics=seq.intrinsics, depth_scale=5000.0) as w:
        w.write_frames(seq)
    bag = tmp_path / "out"
    assert (
        main(
            [
                "export",
                str(rec_path),
                str(bag),
                "--to",
                "rosbag2",
                "--storage",
                "sqlite3",
                "--cloud",
                "-q",
            ]
        )
        == 0
    )
    assert list(bag.glob("*.db3"))
    assert main(["info", str(bag)]) == 0
    out = tmp_path / "again.pcdc"
    assert (
        main(
            [
                "encode",
                str(bag),
                "-o",
                str(out),
                "--cloud-topic",
                "/camera/depth_registered/points",
                "-q",
            ]
        )
        == 0
    )
    with pcdcodec.open(out) as rec:
        assert len(rec) == 2
        assert rec.metadata["ros_cloud_topic"] == "/camera/depth_registered/points"


# -- bad input ------------------------------------------------------------------------------------


def test_bad_bags_raise_clear_errors_and_leave_no_output(tmp_path: Path) -> None:
    store = _store(False)
    color, depth = _small(1)[0]
    out = tmp_path / "o.pcdc"

    def fails(bag: Path, match: str, exc: type[Exception] = InputError, **opts: Any) -> None:
        with pytest.raises(exc, match=match):
            pcdcodec.encode(bag, out, **opts)
        assert not out.exists()
        assert not list(tmp_path.glob(".o.pcdc*"))

    no_depth = write_bag(
        tmp_path / "nodepth.bag",
        [("/cam/color/image_raw", NS, _image(store, False, NS, color, "rgb8"))],
    )
    fails(no_depth, r"has no depth topic .*/cam/color/image_raw")
    rgb_depth = write_bag(
        tmp_path / "8uc3.bag",
        [("/cam/depth/image_raw", NS, _image(store, False, NS, color, "8UC3"))],
    )
    fails(
        rgb_depth,
        r"depth topic '/cam/depth/image_raw' has encoding '8UC3'",
        depth_topic="/cam/depth/image_raw",
    )
    bayer = write_bag(
        tmp_path / "bayer.bag",
        [
            ("/cam/depth/image_raw", NS, _image(store, False, NS, depth, "16UC1")),
            ("/cam/color/image_raw", NS, _image(store, False, NS, color[..., 0], "bayer_rggb8")),
        ],
    )
    fails(
        bayer,
        r"color topic '/cam/color/image_raw' has encoding 'bayer_rggb8'",
        color_topic="/cam/color/image_raw",
    )
    mismatch = write_bag(
        tmp_path / "mismatch.bag",
        [
            ("/cam/depth/image_raw", NS, _image(store, False, NS, depth, "16UC1")),
            ("/cam/color/image_raw", NS, _image(store, False, NS, color[::2, ::2], "rgb8")),
        ],
    )
    fails(
        mismatch,
        r"color topic '/cam/color/image_raw' is 80x60 but depth topic",
        color_topic="/cam/color/image_raw",
    )
    bad_info = write_bag(
        tmp_path / "info.bag",
        [
            ("/cam/depth/camera_info", NS, _info(store, False, NS, 640, 480)),
            ("/cam/depth/image_raw", NS, _image(store, False, NS, depth, "16UC1")),
        ],
    )
    fails(
        bad_info,
        r"camera info topic '/cam/depth/camera_info' is for 640x480 images, "
        r"but '/cam/depth/image_raw' is 160x120",
    )
    flat = np.zeros((1, 100), np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")]))
    cloud = store.types["sensor_msgs/msg/PointCloud2"](
        header=_header(store, False, NS), height=1, width=100,
        fields=[store.types["sensor_msgs/msg/PointField"](name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xyz")],  # noqa: E501
        is_bigendian=False, point_step=12, row_step=1200, data=flat.view(np.uint8).reshape(-1), is_dense=True,  # noqa: E501
    )  # fmt: skip
    flat_bag = write_bag(tmp_path / "flat.bag", [("/cam/points", NS, cloud)])
    fails(flat_bag, r"cloud topic '/cam/points' is not organized", cloud_topic="/cam/points")

    # A truncated bag, and an existing output that survives a failed conversion.
    if RS_BAG.exists():
        cut = tmp_path / "cut.bag"
        cut.write_bytes(RS_BAG.read_bytes()[: RS_BAG.stat().st_size // 2])
        fails(cut, r"cannot read bag .*cut\.bag", DecodeError)
    out.write_bytes(b"keep me")
    with pytest.raises(PcdcodecError):
        pcdcodec.encode(mismatch, out, overwrite=True, color_topic="/cam/color/image_raw")
    assert out.read_bytes() == b"keep me"


def test_a_bad_frame_midway_leaves_no_output(tmp_path: Path) -> None:
    store = _store(True)
    depth = _small(1)[0][1]
    msgs = [("/cam/depth/camera_info", 1, _info(store, True, NS, 160, 120))]
    for k in range(3):
        d = depth if k < 2 else depth[::2, ::2]  # the third frame changes size
        img = _image(store, True, NS + k * 1000, d, "16UC1")
        msgs.append(("/cam/depth/image_raw", NS + k, img))
    bag = write_bag(tmp_path / "b", msgs, ros2=True)
    match = r"'/cam/depth/image_raw': image is 80x60, expected 160x120.*at 1000002000 ns"
    with pytest.raises(InputError, match=match):
        pcdcodec.encode(bag, tmp_path / "o.pcdc")
    assert not (tmp_path / "o.pcdc").exists()


@pytest.mark.skipif(not (SHARED_DATA / "realsense_d435_office").is_dir(), reason="no data")
def test_real_sequence_cloud_bag_colors_exact_and_xyz_within_1e6(tmp_path: Path) -> None:
    """A RealSense D435 sequence (mm depth) as a ROS 2 PointCloud2 bag without CameraInfo."""
    depths = load_depths("realsense_d435", 2)
    colors = load_colors("realsense_d435", 2)
    intr = pcdcodec.CameraIntrinsics(640, 480, 615.0, 615.5, 320.25, 240.75)
    projector = pcdcodec.Projector(intr, depth_scale=1000.0)
    from pcdcodec.convert.rosbag import cloud_array

    store = _store(True)
    msgs = []
    for k, (c, d) in enumerate(zip(colors, depths, strict=True)):
        pts = cloud_array(projector, d, c)
        field = store.types["sensor_msgs/msg/PointField"]
        msg = store.types["sensor_msgs/msg/PointCloud2"](
            header=_header(store, True, NS + k * 33_000_000), height=480, width=640,
            fields=[field(name=n, offset=o, datatype=7, count=1) for n, o in (("x", 0), ("y", 4), ("z", 8), ("rgb", 16))],  # noqa: E501
            is_bigendian=False, point_step=32, row_step=640 * 32,
            data=pts.reshape(-1).view(np.uint8), is_dense=False,
        )  # fmt: skip
        msgs.append(("/rs/depth/color/points", NS + k * 33_000_000, msg))
    bag = write_bag(tmp_path / "rs", msgs, ros2=True)
    summary = pcdcodec.encode(bag, tmp_path / "rs.pcdc", color="h264-lossless")
    assert summary.source["intrinsics_fit_residual_px"] < 1e-2
    with pcdcodec.open(tmp_path / "rs.pcdc") as rec:
        for frame, c, d in zip(rec, colors, depths, strict=True):
            want = projector.to_organized(d)
            got = rec.projector.to_organized(frame.depth)
            valid = np.isfinite(want[..., 2])
            assert np.array_equal(valid, np.isfinite(got[..., 2]))
            assert np.abs(got[valid] - want[valid]).max() <= 1e-6
            assert np.array_equal(frame.color, c)


# -- pass-through of encoded video -------------------------------------------------------------

_VIDEO_MSG = "builtin_interfaces/Time timestamp\nstring frame_id\nuint8[] data\nstring format\n"


def test_compressed_video_passes_through_without_reencoding(tmp_path: Path) -> None:
    from rosbags.typesys import get_types_from_msg

    from pcdcodec.color.base import encode_frames

    store = _store(True)
    store.register(get_types_from_msg(_VIDEO_MSG, "foxglove_msgs/msg/CompressedVideo"))
    frames = _small(6)
    stamps = [NS + k * 33_333_333 for k in range(6)]
    codec = pcdcodec.get_codec("h264", kind="color", gop=3)
    packets, _ = encode_frames(codec, [c for c, _ in frames], stamps)  # type: ignore[arg-type]
    assert len(packets) == 6
    video = store.types["foxglove_msgs/msg/CompressedVideo"]
    time_t = store.types["builtin_interfaces/msg/Time"]
    msgs = [("/cam/depth/camera_info", 1, _info(store, True, NS, 160, 120))]
    for k, (p, (_, d)) in enumerate(zip(packets, frames, strict=True)):
        if k != 4:  # video 4 has no depth: it is kept, since video 5 is decoded from it
            img = _image(store, True, stamps[k], d, "16UC1")
            msgs.append(("/cam/depth/image_raw", stamps[k], img))
        ts = stamps[k] + 2_000_000
        msg = video(
            timestamp=time_t(sec=ts // NS, nanosec=ts % NS), frame_id="cam",
            data=np.frombuffer(p.data, np.uint8), format="h264",
        )  # fmt: skip
        msgs.append(("/cam/color/video", ts, msg))
    msgs.sort(key=lambda m: m[1])
    bag = write_bag(tmp_path / "v", msgs, ros2=True, store=store)
    with pcdcodec.open_source(bag) as src:
        assert "/cam/color/video" in src.video_topics()
    out = tmp_path / "v.pcdc"
    summary = pcdcodec.encode(bag, out, passthrough=True)
    assert summary.frames == 5
    assert summary.dropped == {"color": 1, "depth": 0}
    with pcdcodec.open(out) as rec:
        assert rec.codecs["color"]["id"] == "h264"  # type: ignore[index]
        # The bag's packets, byte for byte, in order, with the keyframes found in the bitstream.
        got = list(rec.packets())
        assert [p.data for p in got] == [p.data for p in packets]
        assert rec.keyframes == [0, 3]
        decoded = {f.timestamp_ns: f.color for f in rec}
    direct = pcdcodec.color.base.decode_packets(codec, packets, 160, 120)
    for k in (0, 1, 2, 3, 5):
        assert np.array_equal(decoded[stamps[k]], direct[k].rgb)


def test_the_missing_camera_note_goes_once_intrinsics_are_given() -> None:
    from tests.conftest import SHARED_DATA

    bag = SHARED_DATA / "bags" / "spot" / "raw.bag"
    if not bag.is_file():
        pytest.skip("the Spot bag of ../shared/data is not present")
    with pcdcodec.open_source(bag) as src:
        assert "no camera info topic: pass intrinsics" in src.describe()["notes"]
        src.intrinsics = pcdcodec.CameraIntrinsics(424, 240, 300.0, 300.0, 212.0, 120.0)
        assert "no camera info topic: pass intrinsics" not in src.describe()["notes"]


# -- seams: layouts, ambiguous clouds and stamps, damaged and oversized images -----------------


def _cloud_bag_msg(
    store: Any, ns: int, z: Any, color: Any, *, step: int = 16, big: bool = False,
    fields: list[tuple[str, int, int, int]] | None = None,
) -> Any:  # fmt: skip
    """A PointCloud2 whose points hold x, y, z (float32) and packed rgb at offsets 0/4/8/12,
    then padding up to ``step`` bytes."""
    h, w = z.shape
    o = ">" if big else "<"
    dt = np.dtype(
        {"names": ["x", "y", "z", "rgb"], "formats": [o + "f4", o + "f4", o + "f4", o + "u4"],
         "offsets": [0, 4, 8, 12], "itemsize": step}
    )  # fmt: skip
    pts = np.zeros((h, w), dt)
    pts["x"], pts["y"], pts["z"] = z * 0.5, z * 0.25, z
    c = color.astype(np.uint32)
    pts["rgb"] = (c[..., 0] << 16) | (c[..., 1] << 8) | c[..., 2]
    field = store.types["sensor_msgs/msg/PointField"]
    if fields is None:
        fields = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 6, 1)]
    return store.types["sensor_msgs/msg/PointCloud2"](
        header=_header(store, False, ns), height=h, width=w,
        fields=[field(name=n, offset=off, datatype=d, count=k) for n, off, d, k in fields],
        is_bigendian=big, point_step=step, row_step=w * step,
        data=pts.reshape(-1).view(np.uint8).copy(), is_dense=False,
    )  # fmt: skip


def _cloud_inputs() -> tuple[list[Any], list[Any]]:
    frames = _small(3)
    zs = [(d.astype(np.float32) / np.float32(5000.0)) + np.float32(1e-5) for _, d in frames]
    return zs, [c for c, _ in frames]


@pytest.mark.parametrize("change", ["point_step", "is_bigendian", "both"])
def test_each_cloud_is_read_with_its_own_layout(tmp_path: Path, change: str) -> None:
    """Clouds with the first cloud's fields but another point_step or byte order are read with
    their own layout: depth and color come back exactly."""
    store = _store(False)
    zs, colors = _cloud_inputs()
    msgs = []
    for k in range(3):
        step = 24 if k > 0 and change in ("point_step", "both") else 16
        big = k > 0 and change in ("is_bigendian", "both")
        msg = _cloud_bag_msg(store, NS + k * 1000, zs[k], colors[k], step=step, big=big)
        msgs.append(("/cam/points", NS + k, msg))
    bag = write_bag(tmp_path / "c.bag", msgs)
    intr = pcdcodec.CameraIntrinsics(160, 120, 131.25, 131.25, 79.75, 59.75)
    with pcdcodec.open_source(bag, cloud_depth="float32", intrinsics=intr) as src:
        got = list(src)
    assert len(got) == 3
    for frame, z, color in zip(got, zs, colors, strict=True):
        assert np.array_equal(frame.depth.view(np.uint32), z.view(np.uint32))
        assert np.array_equal(frame.color, color)


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        (
            [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("z", 0, 7, 1), ("rgb", 12, 6, 1)],
            r"'/cam/points' has the field 'z' twice",
        ),
        (
            [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 6, 0)],
            r"'/cam/points': field 'rgb' has count 0, expected 1",
        ),
        (
            [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 6, 1), ("rgba", 12, 6, 1)],
            r"both an 'rgb' and an 'rgba' field",
        ),
    ],
)
def test_ambiguous_cloud_fields_are_refused_naming_the_field(
    tmp_path: Path, fields: Any, match: str
) -> None:
    store = _store(False)
    zs, colors = _cloud_inputs()
    msg = _cloud_bag_msg(store, NS, zs[0], colors[0], fields=fields)
    bag = write_bag(tmp_path / "c.bag", [("/cam/points", NS, msg)])
    with (
        pytest.raises(InputError, match=match),
        pcdcodec.open_source(bag, cloud_topic="/cam/points") as src,
    ):
        list(src)


def _stamp_bag(path: Path, ros2: bool, stamps: list[tuple[int, int]]) -> Path:
    """Depth images whose header stamps are the raw (sec, nanosec) pairs given."""
    store = _store(ros2)
    depth = _small(1)[0][1]
    t = store.types
    msgs = []
    for k, (sec, nsec) in enumerate(stamps):
        img = _image(store, ros2, NS, depth, "16UC1")
        img.header.stamp = t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        msgs.append(("/cam/depth/image_raw", NS + k * 33_000_000, img))
    return write_bag(path, msgs, ros2=ros2)


@pytest.mark.parametrize("ros2", [False, True])
def test_a_stamp_of_a_second_or_more_of_nanoseconds_is_refused(tmp_path: Path, ros2: bool) -> None:
    name = "stamps" if ros2 else "stamps.bag"
    bag = _stamp_bag(tmp_path / name, ros2, [(5, 0), (5, 1_500_000_000)])
    match = r"stamps(\.bag)?'.*topic '/cam/depth/image_raw': header stamp 5 s 1500000000 ns"
    with pcdcodec.open_source(bag) as src:
        with pytest.raises(DecodeError, match=match):
            list(src)
        with pytest.raises(DecodeError, match=match):
            src.frame_index()


def test_ros1_stamps_after_2038_read_the_same_by_every_path(tmp_path: Path) -> None:
    """ROS 1 seconds are unsigned: stamps at and after 2**31 s are read as such by iteration,
    the frame index and reading a stretch; a recording cannot hold them and says so."""
    big = 1 << 31
    # rosbags writes ROS 1 seconds as int32: -2**31 + s is the same four bytes as 2**31 + s.
    stamps = [(big - 1, 900_000_000), (-big, 0), (-big + 1, 5)]
    bag = _stamp_bag(tmp_path / "late.bag", False, stamps)
    want = [(big - 1) * NS + 900_000_000, big * NS, (big + 1) * NS + 5]
    with pcdcodec.open_source(bag) as src:
        assert [f.timestamp_ns for f in src] == want
        index = src.frame_index()
        assert index.timestamps.tolist() == want
        assert [f.timestamp_ns for f in src.frames(1)] == want[1:]
        assert [f.timestamp_ns for f in src.frames_at(index.slice(1, 3))] == want[1:]
    intr = pcdcodec.CameraIntrinsics(160, 120, 131.25, 131.25, 79.75, 59.75)
    with pytest.raises(InputError, match=r"later than a recording can hold"):
        pcdcodec.encode(bag, tmp_path / "late.pcdc", intrinsics=intr)


def _color_bag(path: Path, payloads: list[bytes], fmt: str = "rgb8; jpeg compressed bgr8") -> Path:
    """A depth Image topic with CameraInfo, and a CompressedImage color topic of ``payloads``."""
    store = _store(False)
    depth = _small(1)[0][1]
    msgs = [("/cam/depth/camera_info", 1, _info(store, False, NS, 160, 120))]
    ctype = store.types["sensor_msgs/msg/CompressedImage"]
    for k, data in enumerate(payloads):
        ts = NS + k * 33_000_000
        msgs.append(("/cam/depth/image_raw", ts, _image(store, False, ts, depth, "16UC1")))
        cmsg = ctype(header=_header(store, False, ts), format=fmt,
                     data=np.frombuffer(data, np.uint8))  # fmt: skip
        msgs.append(("/cam/color/image_raw/compressed", ts + 1, cmsg))
    return write_bag(path, msgs)


def _jpeg(color: Any) -> bytes:
    import imagecodecs

    return bytes(imagecodecs.jpeg8_encode(color, level=90))


def _declaring(data: bytes, width: int, height: int) -> bytes:
    """A JPEG or PNG whose header declares another size (PNG: with its IHDR CRC fixed)."""
    import zlib

    b = bytearray(data)
    if b.startswith(b"\x89PNG"):
        struct.pack_into(">II", b, 16, width, height)
        struct.pack_into(">I", b, 29, zlib.crc32(bytes(b[12:29])))
        return bytes(b)
    i = 2
    while b[i + 1] not in (0xC0, 0xC1, 0xC2):
        i += 2 + struct.unpack_from(">H", b, i + 2)[0]
    struct.pack_into(">HH", b, i + 5, height, width)
    return bytes(b)


def test_a_cut_jpeg_in_a_bag_is_an_error_naming_bag_topic_and_time(tmp_path: Path) -> None:
    color = _small(1)[0][0]
    whole = _jpeg(color)
    bag = _color_bag(tmp_path / "cut.bag", [whole, whole[: len(whole) // 2], whole])
    with pcdcodec.open_source(bag) as src:
        assert src.color_topic == "/cam/color/image_raw/compressed"
        it = iter(src)
        assert np.array_equal(next(it).color.shape, (120, 160, 3))
        with pytest.raises(
            DecodeError,
            match=r"cut\.bag'.*color topic '/cam/color/image_raw/compressed': the JPEG image is "
            r"cut short.*at 1033000000 ns",
        ):
            next(it)


@pytest.mark.parametrize("first", [True, False])
def test_a_jpeg_declaring_30000x30000_is_refused_before_decoding(
    tmp_path: Path, first: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    import imagecodecs

    color = _small(1)[0][0]
    whole = _jpeg(color)
    bomb = _declaring(whole, 30000, 30000)
    payloads = [bomb, whole] if first else [whole, bomb]
    bag = _color_bag(tmp_path / "bomb.bag", payloads)
    decoded: list[bytes] = []
    imread = imagecodecs.imread

    def spy(data: Any, *args: Any, **kwargs: Any) -> Any:
        decoded.append(bytes(data))
        return imread(data, *args, **kwargs)

    monkeypatch.setattr(imagecodecs, "imread", spy)
    with (
        pytest.raises(PcdcodecError, match=r"30000x30000") as err,
        pcdcodec.open_source(bag, color_topic="/cam/color/image_raw/compressed") as src,
    ):
        list(src)
    assert bomb not in decoded  # refused from its header, never handed to a decoder
    assert "bomb.bag" in str(err.value)


def test_a_16bit_png_bomb_without_camera_info_is_refused_before_decoding(tmp_path: Path) -> None:
    import imagecodecs

    store = _store(True)
    depth = _small(1)[0][1]
    png = _declaring(bytes(imagecodecs.png_encode(depth)), 20000, 20000)
    msg = store.types["sensor_msgs/msg/CompressedImage"](
        header=_header(store, True, NS), format="16UC1; png compressed",
        data=np.frombuffer(png, np.uint8),
    )  # fmt: skip
    bag = write_bag(tmp_path / "png", [("/cam/depth/image/compressed", NS, msg)], ros2=True)
    match = r"20000x20000 pixels, more than the 16384 a side"
    with (
        pytest.raises(PcdcodecError, match=match),
        pcdcodec.open_source(bag, depth_topic="/cam/depth/image/compressed") as src,
    ):
        list(src)


def test_a_raw_image_declaring_a_huge_size_is_refused_before_allocating(tmp_path: Path) -> None:
    store = _store(False)
    depth = _small(1)[0][1]
    msgs = [("/cam/depth/camera_info", 1, _info(store, False, NS, 160, 120))]
    for k in range(2):
        img = _image(store, False, NS + k, depth, "16UC1")
        if k == 1:
            img.width, img.height, img.step = 100_000, 100_000, 200_000
        msgs.append(("/cam/depth/image_raw", NS + k, img))
    bag = write_bag(tmp_path / "huge.bag", msgs)
    match = r"huge\.bag'.*image is 100000x100000, expected 160x120"
    with pcdcodec.open_source(bag) as src, pytest.raises(InputError, match=match):
        list(src)


def test_every_error_from_a_bag_names_the_bag(tmp_path: Path) -> None:
    """Errors raised inside the message decoders name only the topic: the source names the
    file, keeping the error's class."""
    store = _store(False)
    color, depth = _small(1)[0]
    msgs = []
    for k in range(2):
        img = _image(store, False, NS + k, color if k else depth, "rgb8" if k else "16UC1")
        msgs.append(("/cam/depth/image_raw", NS + k, img))
    bag = write_bag(tmp_path / "mixed.bag", msgs)
    with pcdcodec.open_source(bag) as src, pytest.raises(InputError) as err:
        list(src)
    assert str(bag) in str(err.value)
    assert "'/cam/depth/image_raw'" in str(err.value)


@pytest.mark.parametrize("kind", [None, "rosbag"])
def test_a_damaged_record_length_costs_no_gigabytes(tmp_path: Path, kind: str | None) -> None:
    """A ROS 1 record header whose length field says 2 GiB: probing and opening the bag end in
    an error naming it, without allocating what the length asks for."""
    import tracemalloc

    store = _store(False)
    depth = _small(1)[0][1]
    bag = write_bag(
        tmp_path / "len.bag", [(DEPTH_TOPIC, NS, _image(store, False, NS, depth, "16UC1"))]
    )
    data = bytearray(bag.read_bytes())
    pos = 13  # after the magic: the bag header record, then the first record after it
    pos += 4 + struct.unpack_from("<I", data, pos)[0]
    pos += 4 + struct.unpack_from("<I", data, pos)[0]
    struct.pack_into("<I", data, pos, 0x7FFFFFF0)
    bag.write_bytes(bytes(data))
    tracemalloc.start()
    try:
        with pytest.raises(DecodeError, match=r"len\.bag"):
            pcdcodec.open_source(bag, kind=kind)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 100_000_000


def test_a_ros1_bag_opens_whatever_its_file_name(tmp_path: Path) -> None:
    store = _store(False)
    depth = _small(1)[0][1]
    bag = write_bag(
        tmp_path / "a.bag", [(DEPTH_TOPIC, NS, _image(store, False, NS, depth, "16UC1"))]
    )
    renamed = tmp_path / "recording.dat"
    shutil.copy(bag, renamed)
    with pcdcodec.open_source(renamed) as src:
        assert np.array_equal(next(iter(src)).depth, depth)


@pytest.mark.parametrize(
    ("point_step", "row_step", "match"),
    [
        (2**32 - 1, 160, r"row_step 160 is shorter than width 10 x point_step 4294967295"),
        (16, 2**32 - 1, r"data is 800 bytes, expected row_step 4294967295 x height 5"),
    ],
)
def test_damaged_cloud_steps_are_errors(point_step: int, row_step: int, match: str) -> None:
    pts = np.zeros((5, 10), np.dtype({"names": ["x", "y", "z"], "formats": ["<f4"] * 3,
                                      "offsets": [0, 4, 8], "itemsize": 16}))  # fmt: skip
    msg = _cloud_msg(pts, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], False)
    msg.point_step, msg.row_step = point_step, row_step
    with pytest.raises(PcdcodecError, match=match):
        rm.cloud_layout(msg, "/pts")


def test_a_color_topic_whose_first_image_is_a_bomb_is_not_dropped_unseen(tmp_path: Path) -> None:
    color = _small(1)[0][0]
    whole = _jpeg(color)
    bag = _color_bag(tmp_path / "bomb.bag", [_declaring(whole, 30000, 30000), whole])
    match = r"bomb\.bag'.*'/cam/color/image_raw/compressed'.*30000x30000.*color_topic=''"
    with pytest.raises(DecodeError, match=match):
        pcdcodec.open_source(bag)
    with pcdcodec.open_source(bag, color_topic="") as src:
        assert [f.color for f in src] == [None, None]


def test_any_source_error_names_its_input_keeping_its_class(tmp_path: Path) -> None:
    """The mechanism every reader relies on: a Source subclass's errors from opening, iterating
    and indexing get the input's path in front unless they name it already."""
    from pcdcodec.sources.base import Source

    class Broken(Source):
        def __init__(self, path: Path, fail_open: bool = False) -> None:
            self.path = path
            if fail_open:
                raise InputError("color must have shape (height, width, 3), got (240, 424, 2)")

        def __iter__(self) -> Any:
            yield None
            raise DecodeError("frame 1 is damaged")

        def frame_index(self) -> Any:
            raise DecodeError(f"{str(self.path)!r} has no index")

    path = tmp_path / "camera.mkv"
    with pytest.raises(InputError, match=r"camera\.mkv'.*: color must have shape"):
        Broken(path, fail_open=True)
    it = iter(Broken(path))
    next(it)
    with pytest.raises(DecodeError, match=r"^'.*camera\.mkv': frame 1 is damaged$"):
        next(it)
    with pytest.raises(DecodeError) as err:
        Broken(path).frame_index()
    assert str(err.value).count("camera.mkv") == 1  # already named: left as it is


# -- a color camera apart from the depth camera, out and back -----------------------------------


def _rotation_about_y(degrees: float) -> np.ndarray[Any, Any]:
    a = np.deg2rad(degrees)
    m = np.eye(4)
    m[0, 0], m[0, 2], m[2, 0], m[2, 2] = np.cos(a), np.sin(a), -np.sin(a), np.cos(a)
    return m


def _recording_with_color_apart(path: Path) -> Path:
    """Three frames of the bundled sample as millimetres, with a color camera of its own
    (other intrinsics, a distortion, 1.5 cm and 2 degrees from the depth camera) and poses."""
    seq = pcdcodec.load_sample(max_frames=3)
    cam = seq.intrinsics
    color_cam = pcdcodec.CameraIntrinsics(
        cam.width, cam.height, 601.5, 600.25, cam.cx + 4.0, cam.cy - 3.0,
        "plumb_bob", (0.11, -0.05, 0.001, 0.002, 0.0),
    )  # fmt: skip
    d2c = _rotation_about_y(2.0)
    d2c[:3, 3] = [-0.015, 0.001, 0.0005]
    with pcdcodec.open(
        path, "w", intrinsics=cam, depth_scale=1000.0, color="ffv1",
        color_intrinsics=color_cam, depth_to_color=d2c,
    ) as rec:  # fmt: skip
        for k, f in enumerate(seq):
            pose = _rotation_about_y(5.0 * k)
            pose[:3, 3] = [0.1 * k, 0.0, 0.02]
            rec.write(f.color, f.depth, f.timestamp_ns, pose=pose)
    return path


def _color_apart_comes_back(
    rec_path: Path, tmp_path: Path, to: str, max_difference: int | None = None
) -> None:
    """Export ``rec_path`` to ``to``, read it back as pcdcodec does, and check the color camera,
    depth_to_color, poses and stamps come back, with depth bit-exact."""
    from .test_rig_out import _read_tf_static

    out = tmp_path / ("apart.bag" if to == "rosbag1" else "apart")
    summary = pcdcodec.export_bag(rec_path, out, to=to, kept=False)  # the camera built anew
    assert summary["topics"][0] == "/tf_static"
    edges, frame_ids, latched = _read_tf_static(out, to)
    # Depth and color in their own frames, the color camera placed in the depth camera's.
    assert frame_ids["/camera/depth/image_raw"] == {"camera_depth_optical_frame"}
    assert frame_ids["/camera/depth/camera_info"] == {"camera_depth_optical_frame"}
    assert frame_ids["/camera/color/image_raw"] == {"camera_color_optical_frame"}
    assert frame_ids["/camera/color/camera_info"] == {"camera_color_optical_frame"}
    assert list(edges) == [("camera_depth_optical_frame", "camera_color_optical_frame")]
    assert latched
    back_path = tmp_path / f"back_{to}.pcdc"
    # (each image keeps its own stamp in the bag, so it pairs again within the same limit)
    options = {} if max_difference is None else {"max_difference": max_difference}
    again = pcdcodec.encode(out, back_path, **options)
    # /tf_static gave the color camera's extrinsics: it is recorded, not left out.
    assert [s["name"] for s in again.left_out] == []
    with pcdcodec.open(rec_path) as rec, pcdcodec.open(back_path) as back:
        assert rec.color_intrinsics is not None
        assert back.intrinsics == rec.intrinsics
        assert back.color_intrinsics == rec.color_intrinsics  # its distortion too
        assert back.depth_to_color is not None
        assert np.allclose(back.depth_to_color, rec.depth_to_color, atol=1e-9)
        assert np.allclose(
            np.linalg.inv(edges[("camera_depth_optical_frame", "camera_color_optical_frame")]),
            rec.depth_to_color,
            atol=1e-9,
        )
        assert back.depth_scale == rec.depth_scale
        assert len(back) == len(rec)
        for a, b in zip(rec, back, strict=True):
            assert b.timestamp_ns == a.timestamp_ns
            assert b.depth.dtype == a.depth.dtype
            assert np.array_equal(b.depth, a.depth)
            assert b.color is not None
            assert a.color is not None
            assert b.color.shape == a.color.shape
            if a.pose is None:
                assert b.pose is None
            else:
                assert b.pose is not None
                assert np.allclose(b.pose, a.pose, atol=1e-9)


@pytest.mark.parametrize("to", ["rosbag1", "rosbag2"])
def test_a_color_camera_apart_is_exported_in_its_own_frame_and_comes_back(
    tmp_path: Path, to: str
) -> None:
    rec_path = _recording_with_color_apart(tmp_path / "apart.pcdc")
    _color_apart_comes_back(rec_path, tmp_path, to)


@pytest.mark.skipif(not RS_BAG.is_file(), reason=f"{RS_BAG} is not present")
@pytest.mark.parametrize("to", ["rosbag1", "rosbag2"])
def test_the_realsense_bag_exported_comes_back_with_its_color_camera(
    tmp_path: Path, to: str
) -> None:
    rec_path = tmp_path / "rs.pcdc"
    pcdcodec.encode(RS_BAG, rec_path, max_difference=300_000_000)
    _color_apart_comes_back(rec_path, tmp_path, to, max_difference=300_000_000)
