"""The librealsense .bag reader, on a real D435 recording (skipped when the data is absent)."""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec import InputError
from pcdcodec.sources.realsense import RealSenseBagSource

from .conftest import SHARED_DATA

BAG = SHARED_DATA / "bags" / "realsense" / "single_depth_color_640x480.bag"
pytestmark = pytest.mark.skipif(not BAG.exists(), reason=f"{BAG} is not present")

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
        assert len(src) == 2
        frames = list(src)
    assert [f.timestamp_ns for f in frames] == [360_815_089_000, 360_981_765_000]
    assert zlib.crc32(frames[1].depth.tobytes()) == RS_DEPTH_CRC
    assert zlib.crc32(frames[1].color.tobytes()) == RS_COLOR_CRC
    # One color frame in the bag: both depth frames take it.
    assert np.array_equal(frames[0].color, frames[1].color)
    with RealSenseBagSource(BAG, max_dt=0.05) as strict:
        assert len(list(strict)) == 0  # the color frame is 101 ms from the nearest depth frame


def test_registration_close_to_librealsense_align() -> None:
    with pcdcodec.open_source(BAG) as src:
        frame = list(src)[1]
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


def test_recording_keeps_both_cameras_and_exact_depth(tmp_path: Path) -> None:
    out = tmp_path / "rs.pcdc"
    with pcdcodec.open_source(BAG) as src:
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
        points, colors = rec[1].to_points()
        assert colors is not None
        assert points.shape[0] == int((frames[1].depth > 0).sum())


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


def test_exported_bag_gives_each_camera_its_own_info(tmp_path: Path) -> None:
    """A two-camera recording exported as a bag: the color CameraInfo is the color camera's
    (not the depth camera's), and the colored cloud is made through the color camera."""
    from rosbags.highlevel import AnyReader

    rec_path = tmp_path / "rs.pcdc"
    with pcdcodec.open_source(BAG) as src:
        depth_cam, color_cam = src.intrinsics, src.color_intrinsics
        assert depth_cam is not None
        assert color_cam is not None
        pcdcodec.encode(src, rec_path, color="ffv1")
    bag = tmp_path / "rs-out.bag"
    pcdcodec.export_bag(rec_path, bag, to="rosbag1", cloud=True)
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
    assert clouds == 2
