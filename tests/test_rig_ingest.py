"""Several cameras in: bags of several cameras, rig files, several inputs into one recording."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import CameraIntrinsics, InputError
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.recording import RigRecording, encode_rig
from pcdcodec.ros.bagwriter import BagWriter, MessageBuilder
from pcdcodec.sources.rig import bag_cameras, merge_by_time, open_inputs
from pcdcodec.sources.rigfile import read_rig

from .conftest import load_colors, load_depths

_MS = 1_000_000
_T0 = 1_700_000_000 * 1_000_000_000  # the bags' clock: stamps of today, as a robot's


def _rot(axis: int, degrees: float) -> np.ndarray[Any, Any]:
    a = np.deg2rad(degrees)
    c, s = np.cos(a), np.sin(a)
    i, j = [k for k in range(3) if k != axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def _pose(axis: int, degrees: float, t: list[float]) -> np.ndarray[Any, Any]:
    m = _rot(axis, degrees)
    m[:3, 3] = t
    return m


@dataclass
class Cam:
    """A camera of the test rig: what goes into the bag, and where it is mounted."""

    ns: str
    intrinsics: CameraIntrinsics
    depths: list[np.ndarray[Any, Any]]
    colors: list[np.ndarray[Any, Any]] | None
    times: list[int]
    float_depth: bool = False  # 32FC1 metres (depth scale 1) instead of 16UC1

    @property
    def frame(self) -> str:
        return f"{self.ns}_depth_optical_frame"


#: Mountings: base_link -> head_mount -> cam_head's frame (a chain of two), and the others
#: straight on base_link.
HEAD_MOUNT = _pose(2, 15.0, [0.05, 0.0, 1.2])
HEAD_OPTICAL = _pose(0, -90.0, [0.02, 0.0, 0.03])
WRIST = _pose(1, 30.0, [0.25, -0.1, 0.05])
SIDE = _pose(0, -12.0, [-0.4, 0.3, 0.2]) @ _rot(2, 90.0)
RIG_POSES = {"cam_head": HEAD_MOUNT @ HEAD_OPTICAL, "cam_wrist": WRIST, "cam_side": SIDE}


def _cameras() -> list[Cam]:
    """Three cameras of different sizes, intrinsics, rates, depth scales and start times,
    from the real sequences (or from the bundled sample where they are absent)."""
    head_d, head_c = load_depths("sample", 6), load_colors("sample", 6)
    if SEQUENCES["realsense_d435"].present:
        seq = SEQUENCES["realsense_d435"]
        wrist_d, wrist_c, wrist_k = load_depths(seq.name, 3), load_colors(seq.name, 3), seq.camera
    else:
        wrist_d = [d[100:340, 200:520].copy() for d in head_d[:3]]
        wrist_c = [c[100:340, 200:520].copy() for c in head_c[:3]]
        wrist_k = CameraIntrinsics(320, 240, 525.0, 525.0, 119.5, 139.5)
    if SEQUENCES["7scenes_redkitchen"].present:
        seq = SEQUENCES["7scenes_redkitchen"]
        side = [
            (d.astype(np.float32) / np.float32(seq.depth_scale)) for d in load_depths(seq.name, 2)
        ]
        side_k = seq.camera
    else:
        side = [(d[::2, ::2].astype(np.float32) / np.float32(5000.0)) for d in head_d[:2]]
        side_k = CameraIntrinsics(320, 240, 262.5, 262.5, 159.75, 119.75)
    for d in side:
        d[d == 0] = np.nan  # no measurement, as drivers publish float depth
    return [
        Cam("cam_head", SEQUENCES["sample"].camera, head_d, head_c,
            [_T0 + 40 * _MS + k * 33_333_333 for k in range(6)]),
        Cam("cam_wrist", wrist_k, wrist_d, wrist_c,
            [_T0 + 53 * _MS + k * 66_666_667 for k in range(3)]),
        Cam("cam_side", side_k, side, None, [_T0 + k * 100 * _MS for k in range(2)], True),
    ]  # fmt: skip


def write_rig_bag(
    path: Path, cams: list[Cam], *, ros2: bool, tf_static: bool = True, offset: int = 0
) -> Path:
    """A bag with each camera under its namespace (color, depth, camera info) and, when asked,
    the mountings in /tf_static."""
    builders = {c.ns: MessageBuilder(ros2, c.frame) for c in cams}
    first = next(iter(builders.values()))
    writer = BagWriter(path, "rosbag2" if ros2 else "rosbag1", "mcap", first)
    messages: list[tuple[int, str, bytes]] = []
    for cam in cams:
        b = builders[cam.ns]
        writer.add(f"/{cam.ns}/depth/image_raw", "sensor_msgs/msg/Image")
        writer.add(f"/{cam.ns}/depth/camera_info", "sensor_msgs/msg/CameraInfo")
        if cam.colors is not None:
            writer.add(f"/{cam.ns}/color/image_raw", "sensor_msgs/msg/Image")
        for k, t in enumerate(cam.times):
            t += offset
            enc = "32FC1" if cam.float_depth else "16UC1"
            messages.append((t, f"/{cam.ns}/depth/image_raw", b.image(t, cam.depths[k], enc)))
            info = b.camera_info(t, cam.intrinsics, "plumb_bob", [0.0] * 5)
            messages.append((t, f"/{cam.ns}/depth/camera_info", info))
            if cam.colors is not None:
                messages.append(
                    (t, f"/{cam.ns}/color/image_raw", b.image(t, cam.colors[k], "rgb8"))
                )
    if tf_static:
        writer.add("/tf_static", "tf2_msgs/msg/TFMessage")
        t0 = min(t for c in cams for t in c.times) + offset
        mounts = {
            "cam_head": [
                ("head_mount", "base_link", HEAD_MOUNT),
                ("cam_head_depth_optical_frame", "head_mount", HEAD_OPTICAL),
            ],
            "cam_wrist": [("cam_wrist_depth_optical_frame", "base_link", WRIST)],
            "cam_side": [("cam_side_depth_optical_frame", "base_link", SIDE)],
        }
        for cam in cams:
            for child, parent, pose in mounts[cam.ns]:
                msg = MessageBuilder(ros2, child).tf(t0, pose, parent)
                messages.append((t0, "/tf_static", msg))
    for t, topic, data in sorted(messages, key=lambda m: m[0]):
        writer.write(topic, t, data)
    writer.close()
    return path


@pytest.fixture(scope="module")
def cams() -> list[Cam]:
    return _cameras()


def _same_depth(a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]) -> bool:
    if a.dtype == np.float32:
        return a.dtype == b.dtype and a.tobytes() == b.tobytes()  # NaN payloads included
    return bool(np.array_equal(a, b)) and a.dtype == b.dtype


def _check_recording(path: Path, cams: list[Cam], names: dict[str, str]) -> None:
    """Every camera of ``cams`` is in the recording at ``path`` under ``names[ns]``, its depth
    bit for bit, its color, stamps, intrinsics and rig pose as built."""
    with pcdcodec.open(path) as rec:
        assert isinstance(rec, RigRecording)
        assert sorted(rec.camera_names) == sorted(names[c.ns] for c in cams)
        for cam in cams:
            info = rec.cameras[names[cam.ns]]
            assert info.intrinsics == cam.intrinsics
            assert info.depth_scale == (1.0 if cam.float_depth else 1000.0)
            assert np.abs(info.rig_pose - RIG_POSES[cam.ns]).max() < 1e-9
            frames = rec.frames(camera=names[cam.ns])
            assert frames.timestamps.tolist() == cam.times
            for k, frame in enumerate(frames):
                assert _same_depth(frame.depth, cam.depths[k])
                if cam.colors is None:
                    assert frame.color is None
                else:
                    err = np.abs(frame.color.astype(int) - cam.colors[k].astype(int)).mean()
                    assert err < 6.0  # h264, lossy
        assert rec.verify().ok


@pytest.mark.parametrize("ros2", [False, True], ids=["ros1", "ros2"])
def test_a_bag_of_three_cameras_is_one_recording_placed_by_tf_static(
    tmp_path: Path, cams: list[Cam], ros2: bool
) -> None:
    bag = write_rig_bag(tmp_path / ("rig" if ros2 else "rig.bag"), cams, ros2=ros2)
    found = bag_cameras(bag)
    assert found.namespaces == ["/cam_head", "/cam_side", "/cam_wrist"]
    assert found.root == "base_link"
    assert found.topics["/cam_side"]["color_topic"] == ""  # not another camera's color
    assert found.topics["/cam_wrist"]["color_topic"] == "/cam_wrist/color/image_raw"
    assert found.placements["cam_head_depth_optical_frame"].path == (
        "base_link",
        "head_mount",
        "cam_head_depth_optical_frame",
    )
    out = tmp_path / "rig.pcdc"
    summary = encode_rig(bag, out)
    assert summary.rig_frame == "base_link"
    assert summary.frames == 11
    assert {n: c.frames for n, c in summary.cameras.items()} == {
        "cam_head": 6,
        "cam_side": 2,
        "cam_wrist": 3,
    }
    assert all(c.bytes_depth > 0 for c in summary.cameras.values())
    assert summary.cameras["cam_side"].bytes_color == 0
    assert summary.warnings == []
    _check_recording(out, cams, {c.ns: c.ns for c in cams})
    with pcdcodec.open(out) as rec:
        assert rec.rig_frame_id == "base_link"
        assert rec.cameras["cam_wrist"].frame_id == "cam_wrist_depth_optical_frame"


def test_frames_are_merged_in_time_order_across_cameras(tmp_path: Path, cams: list[Cam]) -> None:
    bag = write_rig_bag(tmp_path / "rig.bag", cams, ros2=False)
    opened, root = open_inputs([bag])
    try:
        assert root == "base_link"
        merged = [(opened[k].name, f.timestamp_ns) for k, f in merge_by_time(opened)]
    finally:
        for cam in opened:
            cam.source.close()
    expected = sorted((t, c.ns) for c in cams for t in c.times)
    assert [t for _, t in merged] == [t for t, _ in expected]
    assert [n for n, _ in merged] == [n for _, n in expected]
    # Interleaved, not one camera after another.
    assert [n for n, _ in merged[:4]] == ["cam_side", "cam_head", "cam_wrist", "cam_head"]


def test_clock_report_gives_offsets_and_overlap(tmp_path: Path, cams: list[Cam]) -> None:
    summary = encode_rig(write_rig_bag(tmp_path / "rig.bag", cams, ros2=False), tmp_path / "o.pcdc")
    clocks = summary.clocks
    assert clocks.reference == "cam_side"
    assert clocks.offsets == {"cam_side": 0, "cam_head": 40 * _MS, "cam_wrist": 53 * _MS}
    assert clocks.spans["cam_head"] == (cams[0].times[0], cams[0].times[-1])
    assert clocks.overlap == (_T0 + 53 * _MS, _T0 + 100 * _MS)
    assert clocks.warnings == []


def test_a_one_camera_bag_reads_as_before(tmp_path: Path, cams: list[Cam]) -> None:
    bag = write_rig_bag(tmp_path / "one.bag", cams[:1], ros2=False, tf_static=False)
    assert len(bag_cameras(bag)) == 1
    pcdcodec.encode(bag, tmp_path / "plain.pcdc")
    with pcdcodec.open(tmp_path / "plain.pcdc") as rec:
        assert not isinstance(rec, RigRecording)
        assert [f.depth.tobytes() for f in rec] == [d.tobytes() for d in cams[0].depths]


def _write_rig_file(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_several_inputs_and_a_rig_file(tmp_path: Path, cams: list[Cam]) -> None:
    """Two one-camera bags (ROS 1 and ROS 2, one with its clock 30 s later) and a rig file
    with the extrinsics as a quaternion and as a matrix, one depth scale and codec replaced."""
    head = write_rig_bag(tmp_path / "head.bag", cams[:1], ros2=False, tf_static=False)
    write_rig_bag(tmp_path / "wrist", cams[1:2], ros2=True, tf_static=False)
    q = pcdcodec.geometry.transform.matrix_to_quaternion(RIG_POSES["cam_head"][:3, :3]).tolist()
    t = RIG_POSES["cam_head"][:3, 3].tolist()
    rig = _write_rig_file(
        tmp_path / "rig.yaml",
        f"""
frame: base_link
cameras:
  - name: head
    extrinsic:
      translation: [{t[0]!r}, {t[1]!r}, {t[2]!r}]
      rotation: [{q[0]!r}, {q[1]!r}, {q[2]!r}, {q[3]!r}]
    depth_scale: 5000
    depth: zstd
  - name: wrist
    source: wrist
    extrinsic: {RIG_POSES["cam_wrist"].tolist()}
    fps: 15
""",
    )
    out = tmp_path / "rig.pcdc"
    summary = encode_rig([head], out, rig=rig)
    assert summary.rig_frame == "base_link"
    assert summary.cameras["head"].pose_from == "rig file rig.yaml"
    with pcdcodec.open(out) as rec:
        assert isinstance(rec, RigRecording)
        assert rec.camera_names == ["head", "wrist"]
        assert rec.cameras["head"].depth_scale == 5000.0
        assert (rec.cameras["head"].depth_codec or {}).get("id") == "zstd"
        assert rec.cameras["wrist"].fps == 15.0
        assert np.abs(rec.cameras["head"].rig_pose - RIG_POSES["cam_head"]).max() < 1e-9
        assert np.array_equal(rec.cameras["wrist"].rig_pose, RIG_POSES["cam_wrist"])
        for name, cam in (("head", cams[0]), ("wrist", cams[1])):
            got = [f.depth.tobytes() for f in rec.frames(camera=name)]
            assert got == [d.tobytes() for d in cam.depths]


def test_inputs_whose_clocks_do_not_overlap_are_reported(
    tmp_path: Path, cams: list[Cam], capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    head = write_rig_bag(tmp_path / "head.bag", cams[:1], ros2=False)
    late = write_rig_bag(tmp_path / "wrist.bag", cams[1:2], ros2=False, offset=30_000 * _MS)
    out = tmp_path / "rig.pcdc"
    assert main(["encode", str(head), str(late), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "wrote 9 frames of 2 cameras" in text
    assert "rig frame    base_link" in text
    assert "offset +30.013000 s" in text  # wrist's first stamp, 30 s + 13 ms after head's
    assert "overlap      none" in text
    assert "warning: the cameras' stamps do not overlap" in text
    with pcdcodec.open(out) as rec:
        assert rec.camera_names == ["head", "wrist"]
        assert np.abs(rec.cameras["wrist"].rig_pose - WRIST).max() < 1e-9


def test_cli_reads_a_bag_of_several_cameras_as_a_rig(
    tmp_path: Path, cams: list[Cam], capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    bag = write_rig_bag(tmp_path / "rig", cams, ros2=True)
    out = tmp_path / "rig.pcdc"
    assert main(["encode", str(bag), "-o", str(out), "--max-frames", "2"]) == 0
    text = capsys.readouterr().out
    assert "wrote 6 frames of 3 cameras" in text
    for ns in ("cam_head", "cam_wrist", "cam_side"):
        assert f"camera {ns:9}  2 frames" in text
    assert "pose from /tf_static: base_link -> head_mount -> cam_head_depth_optical_frame" in text
    assert main(["encode", str(bag), "-o", str(out), "--overwrite", "--fx", "500"]) == 1
    assert "--fx apply to one camera" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("cameras: []", "key 'cameras': expected a non-empty list"),
        ("frame: rig\ncams: []", "unknown keys ['cams']"),
        ("cameras:\n  - source: a.bag", "camera #1, key 'name'"),
        (
            "cameras:\n  - {name: a, extrinsic: [1, 2]}",
            "camera a, key 'extrinsic': expected a 4 x 4",
        ),
        (
            "cameras:\n  - {name: a, extrinsic: {translation: [0, 0, 0], rotation: [0, 0, 0, 2]}}",
            "camera a, key 'extrinsic.rotation': expected a unit quaternion",
        ),
        (
            "cameras:\n  - {name: a, extrinsic: [[1,0,0,0],[0,2,0,0],[0,0,1,0],[0,0,0,1]]}",
            "camera a, key 'extrinsic'",
        ),
        ("cameras:\n  - {name: a, depth: nosuchcodec}", "camera a, key 'depth'"),
        ("cameras:\n  - {name: a, depth_scale: -3}", "camera a, key 'depth_scale'"),
        ("cameras:\n  - {name: a, colour: h264}", "camera a: unknown keys ['colour']"),
        ("cameras:\n  - {name: a, options: [1]}", "camera a, key 'options': expected a mapping"),
        (
            "cameras:\n  - {name: a, options: {depth_scale: 2}}",
            "camera a, key 'options': give ['depth_scale'] as the camera's own keys",
        ),
        ("cameras:\n  - {name: a}\n  - {name: a}", "given more than once: ['a']"),
        ("cameras: [", "is not YAML"),
        ("cameras:\n  - {name: a, fps: 1" + "0" * 400 + "}", "camera a, key 'fps'"),
        (
            "cameras:\n  - {name: a, extrinsic: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1"
            + "0" * 400
            + "]]}",
            "camera a, key 'extrinsic'",
        ),
    ],
)
def test_rig_file_errors_name_the_file_the_camera_and_the_key(
    tmp_path: Path, text: str, message: str
) -> None:
    rig = _write_rig_file(tmp_path / "bad.yaml", text)
    with pytest.raises(InputError) as info:
        read_rig(rig)
    assert f"rig file {str(rig)!r}" in str(info.value)
    assert message in str(info.value)


def test_rig_file_cameras_need_a_source_a_namespace_and_an_extrinsic(
    tmp_path: Path, cams: list[Cam]
) -> None:
    bag = write_rig_bag(tmp_path / "rig.bag", cams, ros2=False, tf_static=False)
    no_ns = _write_rig_file(tmp_path / "a.yaml", "cameras:\n  - {name: a, source: rig.bag}")
    with pytest.raises(InputError, match=r"camera a, key 'namespace': bag .* holds cameras in"):
        encode_rig([], tmp_path / "o.pcdc", rig=no_ns)
    no_pose = _write_rig_file(
        tmp_path / "b.yaml", "cameras:\n  - {name: a, source: rig.bag, namespace: cam_wrist}"
    )
    with pytest.raises(InputError, match="camera a, key 'extrinsic': no extrinsic"):
        encode_rig([], tmp_path / "o.pcdc", rig=no_pose)
    extra = _write_rig_file(
        tmp_path / "c.yaml",
        "cameras:\n  - {name: a, extrinsic: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}",
    )
    with pytest.raises(InputError, match="feed no camera"):
        encode_rig([bag, bag.with_name("x.bag")], tmp_path / "o.pcdc", rig=extra)
    assert not (tmp_path / "o.pcdc").exists()
    ok = _write_rig_file(
        tmp_path / "d.yaml",
        "frame: base\ncameras:\n  - {name: w, namespace: /cam_wrist, extrinsic: "
        "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}",
    )
    summary = encode_rig([bag], tmp_path / "o.pcdc", rig=ok)
    assert list(summary.cameras) == ["w"]
    assert summary.cameras["w"].frames == 3
    bad_camera = _write_rig_file(
        tmp_path / "e.yaml",
        "cameras:\n  - {name: w, namespace: /cam_wrist, intrinsics: {fx: 1}, extrinsic: "
        "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}",
    )
    with pytest.raises(InputError, match=r"rig file .*e\.yaml', camera w: .*intrinsics"):
        encode_rig([bag], tmp_path / "o2.pcdc", rig=bad_camera)
    assert not (tmp_path / "o2.pcdc").exists()


# -- archive ----------------------------------------------------------------------------------


def _archive_bag(tmp_path: Path, cams: list[Cam]) -> Path:
    folder = tmp_path / "runs"
    folder.mkdir()
    return write_rig_bag(folder / "robot.bag", cams, ros2=False)


def test_archive_keeps_every_camera_of_a_bag_of_several(tmp_path: Path, cams: list[Cam]) -> None:
    from pcdcodec.archive import archive

    _archive_bag(tmp_path, cams)
    out = tmp_path / "out"
    summary = archive([tmp_path / "runs"], out, workers=1, processes=False, verify=True)
    assert summary.ok, summary.to_text()
    assert summary.items[0].state == "verified"
    assert summary.items[0].frames == 11
    _check_recording(out / "runs" / "robot.pcdc", cams, {c.ns: c.ns for c in cams})


def test_archive_segments_of_a_rig_hold_every_camera_in_time_order(
    tmp_path: Path, cams: list[Cam]
) -> None:
    """Cut by time: each segment is a rig of every camera, and the segments together hold each
    camera's frames once, bit for bit."""
    from pcdcodec.archive import tasks
    from pcdcodec.archive.rig_tasks import RigIndex
    from pcdcodec.archive.settings import _writer_options

    bag = _archive_bag(tmp_path, cams)
    opts, keyframes = _writer_options("h264", "depthac", 30.0)
    probe = tasks._probe(str(bag), {}, 4, 1)
    index = probe["index"]
    assert isinstance(index, RigIndex)
    assert probe["frames"] == len(index) == 11
    assert sorted(probe["camera"]["cameras"]) == ["cam_head", "cam_side", "cam_wrist"]
    plan = tasks.segment_plan(probe["frames"], probe["size"], 4, keyframes)
    assert len(plan) == 3
    got: dict[str, list[tuple[int, bytes]]] = {c.ns: [] for c in cams}
    for k, (start, stop) in enumerate(plan):
        part = tmp_path / "parts" / f"seg-{k}.pcdc"
        result = tasks._encode_segment(
            str(bag), {}, str(part), start, stop, opts, True, index.slice(start, stop)
        )
        assert result == tasks._existing_segment(str(part), True)
        with pcdcodec.open(part) as rec:
            assert isinstance(rec, RigRecording)
            assert rec.camera_names == ["cam_head", "cam_side", "cam_wrist"]
            times = []
            for name in rec.camera_names:
                assert np.abs(rec.cameras[name].rig_pose - RIG_POSES[name]).max() < 1e-9
                for f in rec.frames(camera=name):
                    got[name].append((f.timestamp_ns, f.depth.tobytes()))
                    times.append(f.timestamp_ns)
            assert result["frames"] == len(times)
            merged = sorted(t for c in cams for t in c.times)
            stop_t = merged[stop] if stop is not None and stop < len(merged) else None
            assert all(merged[start] <= t and (stop_t is None or t < stop_t) for t in times)
    for cam in cams:
        assert got[cam.ns] == list(zip(cam.times, [d.tobytes() for d in cam.depths], strict=True))


def test_archive_of_a_rig_in_segments_verifies(tmp_path: Path, cams: list[Cam]) -> None:
    from pcdcodec.archive import archive

    _archive_bag(tmp_path, cams)
    out = tmp_path / "out"
    summary = archive(
        [tmp_path / "runs"], out, workers=1, processes=False, verify=True, segment_frames=4
    )
    assert summary.ok, summary.to_text()
    item = summary.items[0]
    assert item.state == "verified"
    # Three segments joined camera by camera (a camera may have no frames in a segment).
    assert item.segments == 3
    assert item.frames == 11
    _check_recording(out / "runs" / "robot.pcdc", cams, {c.ns: c.ns for c in cams})


@pytest.mark.parametrize(
    ("depth_topics", "namespaces"),
    [
        (["/cam_head/depth/image_raw", "/cam_wrist/depth/image_raw"], ["/cam_head", "/cam_wrist"]),
        (
            ["/camera/depth/image_rect_raw", "/camera/aligned_depth_to_color/image_raw"],
            ["/camera"],
        ),
        (["/robot/left/depth/image", "/robot/right/depth/image"], ["/robot/left", "/robot/right"]),
        (["/depth/image_raw"], ["/"]),
        (["/camera/depth_registered/image_raw", "/camera/depth/image"], ["/camera"]),
    ],
)
def test_namespaces_of_depth_topics(depth_topics: list[str], namespaces: list[str]) -> None:
    from pcdcodec.ros.topics import TopicCandidate, camera_namespaces

    cands = [TopicCandidate(t, "sensor_msgs/msg/Image", 3, "depth") for t in depth_topics]
    cands.append(TopicCandidate("/other/color/image_raw", "sensor_msgs/msg/Image", 3, "color"))
    assert camera_namespaces(cands) == namespaces


def test_camera_names_from_namespaces_and_files() -> None:
    from pcdcodec.sources.rig import camera_name

    assert camera_name("/robot/cam_head") == "cam_head"
    assert camera_name("2024-05 run.bag") == "cam_2024_05_run"
    assert camera_name("head.bag", ["head"]) == "head_2"
    assert camera_name("/") == "camera"


def test_a_bag_of_two_cloud_cameras(tmp_path: Path, cams: list[Cam]) -> None:
    """Organized PointCloud2 topics in two namespaces, with their CameraInfo: a camera each,
    each cloud's z back as whole depth units, bit for bit."""
    from pcdcodec import Projector
    from pcdcodec.ros.clouds import cloud_array

    head, wrist = cams[0], cams[1]
    builders = {c.ns: MessageBuilder(False, c.frame) for c in (head, wrist)}
    writer = BagWriter(tmp_path / "clouds.bag", "rosbag1", "mcap", builders["cam_head"])
    messages = []
    for cam in (head, wrist):
        b = builders[cam.ns]
        writer.add(f"/{cam.ns}/depth/points", "sensor_msgs/msg/PointCloud2")
        writer.add(f"/{cam.ns}/depth/camera_info", "sensor_msgs/msg/CameraInfo")
        projector = Projector(cam.intrinsics, depth_scale=1000.0)
        for k, t in enumerate(cam.times[:2]):
            assert cam.colors is not None
            pts = cloud_array(projector, cam.depths[k], cam.colors[k])
            messages.append((t, f"/{cam.ns}/depth/points", b.cloud(t, pts)))
            info = b.camera_info(t, cam.intrinsics, "plumb_bob", [0.0] * 5)
            messages.append((t, f"/{cam.ns}/depth/camera_info", info))
    for t, topic, data in sorted(messages, key=lambda m: m[0]):
        writer.write(topic, t, data)
    writer.close()
    found = bag_cameras(tmp_path / "clouds.bag")
    assert found.namespaces == ["/cam_head", "/cam_wrist"]
    assert found.topics["/cam_wrist"]["cloud_topic"] == "/cam_wrist/depth/points"
    summary = encode_rig(tmp_path / "clouds.bag", tmp_path / "clouds.pcdc")
    assert summary.rig_frame == "rig"  # no /tf_static: the cameras are not placed
    assert len(summary.warnings) == 2
    with pcdcodec.open(tmp_path / "clouds.pcdc") as rec:
        assert isinstance(rec, RigRecording)
        for cam in (head, wrist):
            info = rec.cameras[cam.ns]
            assert info.intrinsics == cam.intrinsics
            assert info.depth_scale == 1000.0
            got = [f.depth for f in rec.frames(camera=cam.ns)]
            assert [g.tobytes() for g in got] == [d.tobytes() for d in cam.depths[:2]]


def test_rig_file_options_go_to_the_cameras_reader(tmp_path: Path) -> None:
    from pcdcodec.datasets import sample_dir
    from pcdcodec.sources.rigfile import open_rig

    sample = sample_dir()
    pose = "extrinsic: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]"
    good = _write_rig_file(
        tmp_path / "good.yaml",
        f"cameras:\n  - {{name: a, source: {sample}, options: {{layout: tum}}, {pose}}}",
    )
    cams = open_rig(good)
    try:
        assert len(list(cams[0].source)) == 15
    finally:
        for cam in cams:
            cam.source.close()
    bad = _write_rig_file(
        tmp_path / "bad.yaml",
        f"cameras:\n  - {{name: a, source: {sample}, options: {{layout: bogus}}, {pose}}}",
    )
    with pytest.raises(InputError) as info:
        open_rig(bad)
    assert f"rig file {str(bad)!r}" in str(info.value)
    assert "camera a" in str(info.value)
    assert "layout must be" in str(info.value)
