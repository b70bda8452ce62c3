"""Recordings of several cameras going out: bags, folders, the viewer, joins, recovery, info."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import CameraIntrinsics
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.cli import main
from pcdcodec.recording import CameraSpec, RigRecording, RigWriter

from .conftest import load_colors, load_depths, to_metres

_MS = 1_000_000


def _rot(axis: int, degrees: float) -> np.ndarray[Any, Any]:
    a = np.deg2rad(degrees)
    c, s = np.cos(a), np.sin(a)
    i, j = [k for k in range(3) if k != axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


@dataclass
class Cam:
    spec: CameraSpec
    depths: list[np.ndarray[Any, Any]]
    colors: list[np.ndarray[Any, Any]] | None
    times: list[int]

    @property
    def pose(self) -> np.ndarray[Any, Any]:
        return np.eye(4) if self.spec.rig_pose is None else np.asarray(self.spec.rig_pose)


#: The wrist camera's color camera, apart from its depth camera: 4 cm to the side.
D2C = np.eye(4)
D2C[0, 3] = -0.04


def _cameras(first_ms: int = 1_000) -> list[Cam]:
    """Three small cameras: other sizes, intrinsics, depth scales, rates and start times; the
    wrist's color camera apart from its depth camera; the side camera depth only. From the
    real sequences when present, else from the bundled sample."""
    tum = SEQUENCES["sample"].camera
    head_d, head_c = load_depths("sample", 4), load_colors("sample", 4)
    pose_wrist = _rot(1, 30.0)
    pose_wrist[:3, 3] = [0.25, -0.1, 0.05]
    pose_side = _rot(0, -12.0) @ _rot(2, 90.0)
    pose_side[:3, 3] = [-0.4, 0.3, 0.2]
    if SEQUENCES["realsense_d435"].present:
        seq = SEQUENCES["realsense_d435"]
        wrist_d, wrist_c = load_depths(seq.name, 3), load_colors(seq.name, 3)
        wrist_cam, wrist_scale = seq.camera, seq.depth_scale
    else:
        wrist_d = [d[100:340, 200:520].copy() for d in head_d[:3]]
        wrist_c = [c[100:340, 200:520].copy() for c in head_c[:3]]
        wrist_cam = CameraIntrinsics(320, 240, 525.0, 525.0, 119.5, 139.5)
        wrist_scale = 1000.0
    wrist_color_cam = CameraIntrinsics(
        wrist_cam.width, wrist_cam.height, wrist_cam.fx * 1.02, wrist_cam.fy * 1.02,
        wrist_cam.cx + 3.0, wrist_cam.cy - 2.0,
    )  # fmt: skip
    if SEQUENCES["7scenes_redkitchen"].present:
        seq = SEQUENCES["7scenes_redkitchen"]
        side_d = load_depths(seq.name, 3)
        side_cam, side_scale = seq.camera, seq.depth_scale
    else:
        side_d = [d[::2, ::2].copy() for d in head_d[:3]]
        side_cam = CameraIntrinsics(320, 240, 262.5, 262.5, 159.75, 119.75)
        side_scale = 2500.0
    t0 = first_ms * _MS
    return [
        Cam(
            CameraSpec("head", tum, 5000.0, fps=30.0, depth="zstd"),
            head_d,
            head_c,
            [t0 + k * 33_333_333 for k in range(len(head_d))],
        ),
        Cam(
            CameraSpec(
                "wrist",
                wrist_cam,
                wrist_scale,
                fps=15.0,
                rig_pose=pose_wrist,
                color_intrinsics=wrist_color_cam,
                depth_to_color=D2C,
            ),
            wrist_d,
            wrist_c,
            [t0 + 13 * _MS + k * 66_666_667 for k in range(len(wrist_d))],
        ),
        Cam(
            CameraSpec(
                "side",
                side_cam,
                side_scale,
                fps=10.0,
                color=None,
                depth="zstd",
                rig_pose=pose_side,
                frame_id="side_link",
            ),
            side_d,
            None,
            [t0 - 40 * _MS + k * 100 * _MS for k in range(len(side_d))],
        ),
    ]


def write_rig(path: Path, cams: list[Cam], *, finish: bool = True) -> RigWriter:
    """The cameras' frames written in the order they happened, as a live rig hands them in."""
    events = sorted((t, c, k) for c, cam in enumerate(cams) for k, t in enumerate(cam.times))
    w = RigWriter(path, [c.spec for c in cams], metadata={"site": "lab"})
    for t, c, k in events:
        cam = cams[c]
        w.write(cam.spec.name, None if cam.colors is None else cam.colors[k], cam.depths[k], t)
    if finish:
        w.close()
    return w


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Cam]]:
    cams = _cameras()
    path = tmp_path_factory.mktemp("rig") / "rig.pcdc"
    write_rig(path, cams)
    return path, cams


# -- export ------------------------------------------------------------------------------


@pytest.mark.parametrize("to", ["rosbag1", "rosbag2"])
def test_export_writes_every_camera_under_its_namespace_with_tf_static(
    rig: tuple[Path, list[Cam]], tmp_path: Path, to: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path, cams = rig
    out = tmp_path / ("rig.bag" if to == "rosbag1" else "rig_bag")
    assert main(["export", str(path), str(out), "--to", to]) == 0
    said = capsys.readouterr().out
    for cam in cams:
        assert f"camera {cam.spec.name}: {len(cam.times)} frames under /{cam.spec.name}" in said
    # Each namespace reads back with pcdcodec's own bag reader: depth bit-exact.
    for cam in cams:
        ns = f"/{cam.spec.name}"
        with pcdcodec.open_source(
            out,
            depth_topic=f"{ns}/depth/image_raw",
            color_topic=f"{ns}/color/image_raw" if cam.colors is not None else "",
            info_topic=f"{ns}/depth/camera_info",
        ) as back:
            assert back.intrinsics == cam.spec.intrinsics
            frames = list(back)
        assert [f.timestamp_ns for f in frames] == cam.times
        for k, frame in enumerate(frames):
            if cam.spec.depth_scale == 1000.0:  # 16UC1 millimetres
                assert frame.depth.dtype == np.uint16
                assert np.array_equal(frame.depth, cam.depths[k])
            else:  # 32FC1 metres
                expected = to_metres(cam.depths[k], cam.spec.depth_scale)
                assert np.array_equal(frame.depth, expected, equal_nan=True)
            assert frame.pose is None  # /tf_static places the cameras, it is no trajectory
            if cam.colors is not None:
                assert frame.color is not None
                assert frame.color.shape == cam.colors[k].shape
    # /tf_static holds the rig poses (and the wrist's color camera in the wrist's frame).
    edges, frame_ids, latched = _read_tf_static(out, to)
    expected = {("rig", c.spec.frame_id or c.spec.name): c.pose for c in cams}
    expected[("wrist", "wrist_color")] = np.linalg.inv(D2C)
    assert set(edges) == set(expected)
    for key, pose in expected.items():
        assert np.allclose(edges[key], pose, atol=1e-9), key
    assert latched
    # Each camera's messages are in its own frame; the wrist's color images in its color frame.
    assert frame_ids["/head/depth/image_raw"] == {"head"}
    assert frame_ids["/side/depth/image_raw"] == {"side_link"}
    assert frame_ids["/wrist/depth/image_raw"] == {"wrist"}
    assert frame_ids["/wrist/color/image_raw"] == {"wrist_color"}
    assert frame_ids["/wrist/color/camera_info"] == {"wrist_color"}
    assert "/side/color/image_raw" not in frame_ids


def _read_tf_static(
    bag: Path, to: str
) -> tuple[dict[tuple[str, str], np.ndarray[Any, Any]], dict[str, set[str]], bool]:
    """With rosbags: /tf_static's transforms as matrices, each topic's frame ids, and whether
    /tf_static is latched."""
    from rosbags.highlevel import AnyReader

    from pcdcodec.geometry.transform import quaternion_to_matrix

    edges: dict[tuple[str, str], np.ndarray[Any, Any]] = {}
    frame_ids: dict[str, set[str]] = {}
    with AnyReader([bag]) as reader:
        static = [c for c in reader.connections if c.topic == "/tf_static"]
        assert len(static) == 1
        ext = static[0].ext
        if to == "rosbag1":
            latched = bool(getattr(ext, "latching", 0))
        else:
            latched = any(q.durability.name == "TRANSIENT_LOCAL" for q in ext.offered_qos_profiles)
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/tf_static":
                for tf in msg.transforms:
                    r, t = tf.transform.rotation, tf.transform.translation
                    m = np.eye(4)
                    m[:3, :3] = quaternion_to_matrix((r.x, r.y, r.z, r.w))
                    m[:3, 3] = [t.x, t.y, t.z]
                    edges[(tf.header.frame_id, tf.child_frame_id)] = m
            elif conn.topic != "/tf":
                frame_ids.setdefault(conn.topic, set()).add(msg.header.frame_id)
    return edges, frame_ids, latched


def test_export_of_a_rig_through_the_api(rig: tuple[Path, list[Cam]], tmp_path: Path) -> None:
    path, _ = rig
    with pcdcodec.open(path) as rec:
        summary = pcdcodec.export_bag(rec, tmp_path / "a.bag", namespace="robot", max_frames=4)
    assert summary["frames"] == 4
    assert sum(summary["cameras"].values()) == 4
    assert "/robot/head/depth/image_raw" in summary["topics"]
    assert summary["topics"][0] == "/tf_static"
    with pytest.raises(pcdcodec.InputError, match="frame_id cannot be given"):
        pcdcodec.export_bag(path, tmp_path / "b.bag", frame_id="x")
    with pytest.raises(pcdcodec.InputError, match="camera 'head': compressedDepth"):
        pcdcodec.export_bag(path, tmp_path / "c.bag", compressed_depth=True)
    assert not (tmp_path / "c.bag").exists()


# -- info, verify, decode ------------------------------------------------------------------


def test_info_lists_every_camera(
    rig: tuple[Path, list[Cam]], capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    path, cams = rig
    assert main(["info", str(path)]) == 0
    said = capsys.readouterr().out
    assert "recording of 3 cameras, format version 3" in said
    assert "camera side (frame side_link)" in said
    assert "rotation 30.00 deg" in said  # the wrist's
    assert said.count("    depth      ") == 3
    assert main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["rig_frame_id"] == "rig"
    assert info["frames"] == sum(len(c.times) for c in cams)
    for cam, got in zip(cams, info["cameras"], strict=True):
        assert got["name"] == cam.spec.name
        assert got["frames"] == len(cam.times)
        assert got["intrinsics"] == cam.spec.intrinsics.to_dict()
        assert got["depth_scale"] == cam.spec.depth_scale
        assert got["fps"] == cam.spec.fps
        assert got["first_timestamp_ns"] == cam.times[0]
        assert np.array_equal(np.asarray(got["rig_pose"]), cam.pose)
        assert got["codecs"]["depth"]["id"] == cam.spec.depth
        assert (got["codecs"]["color"] is None) == (cam.spec.color is None)
    assert info["cameras"][1]["depth_to_color"] == D2C.tolist()


def test_verify_checks_every_camera(
    rig: tuple[Path, list[Cam]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, cams = rig
    assert main(["verify", str(path)]) == 0
    said = capsys.readouterr().out
    for cam in cams:
        assert f"camera {cam.spec.name}: {len(cam.times)} frames, OK" in said
    assert f"{sum(len(c.times) for c in cams)} frames checked, OK" in said
    # A flipped byte in the side camera's last depth frame (zstd, uncompressed chunks) is found
    # and named by its camera.
    data = bytearray(path.read_bytes())
    with pcdcodec.open(path) as rec:
        side = rec.frames("side")
        offset = int(side.index.offsets["/camera/depth"][-1])
    assert offset > 0
    bad = tmp_path / "bad.pcdc"
    data[offset + 200] ^= 0xFF
    bad.write_bytes(bytes(data))
    assert main(["verify", str(bad)]) == 1
    said = capsys.readouterr().out
    # Only the camera whose chunk it is has the problem.
    assert "camera head: 4 frames, OK" in said
    assert "camera wrist: 3 frames, OK" in said
    assert "camera side: 3 frames, 1 problem(s)" in said
    assert f"camera 'side': {str(bad)!r}: frame 2 " in said
    assert "problem(s)" in said.splitlines()[-1]


def test_decode_writes_one_folder_per_camera(
    rig: tuple[Path, list[Cam]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    path, cams = rig
    out = tmp_path / "out"
    assert main(["decode", str(path), "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "of 3 cameras" in said
    layout = json.loads((out / "rig.json").read_text())
    assert layout["rig_frame_id"] == "rig"
    for cam, entry in zip(cams, layout["cameras"], strict=True):
        name = cam.spec.name
        assert f"camera {name}, {len(cam.times)} frames" in said
        assert entry["folder"] == name
        assert np.array_equal(np.asarray(entry["rig_pose"]), cam.pose)
        with pcdcodec.open_source(out / name, depth_scale=cam.spec.depth_scale) as back:
            assert back.intrinsics == cam.spec.intrinsics
            assert (back.color_intrinsics is not None) == (cam.spec.color_intrinsics is not None)
            frames = list(back)
        assert [f.timestamp_ns for f in frames] == cam.times
        for k, frame in enumerate(frames):
            assert np.array_equal(frame.depth, cam.depths[k])
            assert (frame.color is None) == (cam.colors is None)
    assert not (out / "side" / "rgb").exists() or not any((out / "side" / "rgb").iterdir())
    # Into a folder that is not empty: only with --overwrite.
    assert main(["decode", str(path), "-o", str(out)]) == 1
    assert main(["decode", str(path), "-o", str(out), "--overwrite", "-q"]) == 0


# -- join ----------------------------------------------------------------------------------


def _split(cams: list[Cam], at: int) -> tuple[list[Cam], list[Cam]]:
    """Each camera's frames before and from ``at`` ms after the first frame."""
    cut = min(t for c in cams for t in c.times) + at * _MS

    def part(keep: Any) -> list[Cam]:
        out = []
        for c in cams:
            ks = [k for k, t in enumerate(c.times) if keep(t)]
            out.append(
                Cam(
                    c.spec,
                    [c.depths[k] for k in ks],
                    None if c.colors is None else [c.colors[k] for k in ks],
                    [c.times[k] for k in ks],
                )
            )
        return out

    return part(lambda t: t < cut), part(lambda t: t >= cut)


def test_join_keeps_every_camera(
    rig: tuple[Path, list[Cam]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, cams = rig
    first, second = _split(cams, 100)
    a, b = tmp_path / "a.pcdc", tmp_path / "b.pcdc"
    write_rig(a, first)
    write_rig(b, second)
    joined = tmp_path / "ab.pcdc"
    assert main(["join", str(a), str(b), "-o", str(joined)]) == 0
    said = capsys.readouterr().out
    assert f"joined {sum(len(c.times) for c in cams)} frames of 2 recordings" in said
    for cam in cams:
        assert f"camera {cam.spec.name}: {len(cam.times)} frames" in said
    with pcdcodec.open(joined) as rec:
        assert isinstance(rec, RigRecording)
        assert rec.index.indexed
        assert rec.metadata == {"site": "lab"}
        for cam in cams:
            frames = rec.frames(cam.spec.name)
            assert frames.timestamps.tolist() == cam.times
            assert np.array_equal(rec.cameras[cam.spec.name].rig_pose, cam.pose)
            for k, frame in enumerate(frames):
                assert np.array_equal(frame.depth, cam.depths[k])
                assert (frame.color is None) == (cam.colors is None)
        assert rec.verify().ok
    # Each camera's sequence numbers run on across the parts, as from one writer.
    from mcap.reader import make_reader

    with joined.open("rb") as f:
        seqs: dict[str, list[int]] = {}
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.topic.endswith("/depth"):
                seqs.setdefault(channel.topic, []).append(message.sequence)
    assert {t: sorted(s) for t, s in seqs.items()} == {
        f"/{c.spec.name}/depth": list(range(len(c.times))) for c in cams
    }


def test_join_refuses_parts_of_other_cameras_or_overlapping_times(
    rig: tuple[Path, list[Cam]], tmp_path: Path
) -> None:
    from pcdcodec.recording.join import join

    path, cams = rig
    first, second = _split(cams, 100)
    a, b = tmp_path / "a.pcdc", tmp_path / "b.pcdc"
    write_rig(a, first)
    write_rig(b, second)
    out = tmp_path / "out.pcdc"
    with pytest.raises(pcdcodec.InputError, match=r"camera 'head' of .* starts at"):
        join([b, a], out)
    with pytest.raises(pcdcodec.InputError, match="starts at"):
        join([path, b], out)
    # Another camera set, or a camera with other settings, cannot follow.
    fewer = tmp_path / "fewer.pcdc"
    write_rig(fewer, second[:2])
    with pytest.raises(
        pcdcodec.InputError,
        match=r"holds the cameras \['head', 'wrist'\], .* the cameras \['head', 'wrist', 'side'\]",
    ):
        join([a, fewer], out)
    moved = [Cam(c.spec, c.depths, c.colors, c.times) for c in second]
    spec = moved[2].spec
    moved[2] = Cam(
        CameraSpec(spec.name, spec.intrinsics, spec.depth_scale, fps=spec.fps, color=None,
                   depth="zstd", rig_pose=np.eye(4), frame_id=spec.frame_id),
        moved[2].depths, None, moved[2].times,
    )  # fmt: skip
    other = tmp_path / "other.pcdc"
    write_rig(other, moved)
    with pytest.raises(pcdcodec.InputError, match=r"camera 'side' has other settings \(rig_pose\)"):
        join([a, other], out)
    # A one-camera recording cannot follow a rig either.
    one = tmp_path / "one.pcdc"
    with pcdcodec.open(one, "w", intrinsics=cams[2].spec.intrinsics, color=None) as w:
        w.write(None, cams[2].depths[0], 5 * 10**9)
    with pytest.raises(pcdcodec.InputError, match="it holds one camera"):
        join([a, one], out)
    assert not out.exists()
    # A killed rig must be recovered first.
    killed = tmp_path / "killed.pcdc"
    write_rig(killed, second, finish=False).abort()
    with pytest.raises(pcdcodec.DecodeError, match="recover"):
        join([a, killed], out)


# -- recover -------------------------------------------------------------------------------


def _check_prefix(path: Path, cams: list[Cam], *, decode: bool = True) -> dict[str, int]:
    """Each camera's frames in the recording at ``path`` are the first of its own, bit-exact
    (decoded when ``decode``); returns how many each has."""
    counts = {}
    with pcdcodec.open(path) as rec:
        assert isinstance(rec, RigRecording)
        assert rec.index.indexed
        assert rec.camera_names == [c.spec.name for c in cams]
        for cam in cams:
            frames = rec.frames(cam.spec.name)
            n = len(frames)
            assert frames.timestamps.tolist() == cam.times[:n]
            if decode:
                for k, frame in enumerate(frames):
                    assert np.array_equal(frame.depth, cam.depths[k])
            counts[cam.spec.name] = n
        if decode:
            assert rec.verify().ok
    return counts


def test_recover_a_killed_rig_keeps_every_cameras_complete_frames(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cams = _cameras()
    killed = tmp_path / "killed.pcdc"
    w = write_rig(killed, cams, finish=False)
    w.flush()
    complete = w.frames_complete
    w.abort()  # as after SIGKILL: no seals, no index
    assert complete["side"] == len(cams[2].times)  # depth only: nothing held back
    out = tmp_path / "recovered.pcdc"
    assert main(["recover", str(killed), "-o", str(out)]) == 0
    said = capsys.readouterr().out
    counts = _check_prefix(out, cams)
    assert counts == complete
    assert f"recovered {sum(counts.values())} frames" in said
    for name, n in counts.items():
        assert f"camera {name}: {n} frames" in said
    with pcdcodec.open(out) as rec:
        seals = [k for k in rec.index.metadata if k.startswith("pcdcodec.seal")]
        assert sorted(seals) == sorted(f"pcdcodec.seal.{c.spec.name}" for c in cams)
        assert rec.metadata == {"site": "lab"}
        assert np.array_equal(rec.cameras["wrist"].rig_pose, cams[1].pose)
    # The recovered rig joins like any other.
    from pcdcodec.recording.join import join

    later = [Cam(c.spec, c.depths, c.colors, [t + 10**10 for t in c.times]) for c in cams]
    more = tmp_path / "more.pcdc"
    write_rig(more, later)
    assert join([out, more], tmp_path / "j.pcdc") == sum(counts.values()) + sum(
        len(c.times) for c in cams
    )


def test_recover_a_rig_cut_short_at_any_byte(rig: tuple[Path, list[Cam]], tmp_path: Path) -> None:
    path, cams = rig
    data = path.read_bytes()
    with pcdcodec.open(path) as rec:
        first_message = min(
            int(o)
            for name in rec.camera_names
            for o in rec.frames(name).index.offsets["/camera/depth"]
        )
        end = rec.index.size
    # Every few bytes of the records before the first message, and spread over the rest.
    cuts = sorted(
        {
            *range(0, first_message + 64, 7),
            *np.linspace(first_message, len(data), 25).astype(int).tolist(),
        }
    )
    previous: dict[str, int] | None = None
    recovered = 0
    for cut in cuts:
        cut_file = tmp_path / "cut.pcdc"
        cut_file.write_bytes(data[:cut])
        out = tmp_path / "out.pcdc"
        try:
            pcdcodec.recover(cut_file, out, overwrite=True)
        except pcdcodec.PcdcodecError as exc:
            failed = exc
        else:
            failed = None
        if failed is not None:
            assert str(cut_file) in str(failed)
            assert cut < first_message, cut  # only a cut in the records loses it all
            continue
        recovered += 1
        counts = _check_prefix(out, cams, decode=cut % 3 == 0)
        if previous is not None:  # more of the file never gives fewer frames
            assert all(counts[n] >= previous[n] for n in counts), cut
        previous = counts
    assert recovered >= 20
    assert previous == {c.spec.name: len(c.times) for c in cams}  # the last cut: only the index
    assert end <= len(data)


# -- view ----------------------------------------------------------------------------------


def test_view_shows_every_camera_in_its_place_and_the_fused_cloud(
    rig: tuple[Path, list[Cam]], tmp_path: Path
) -> None:
    pytest.importorskip("rerun")
    from .test_viewer import _blobs, _contents, _logged_depths

    path, cams = rig
    out = tmp_path / "rig.rrd"
    assert main(["view", str(path), "--save", str(out), "--stride", "4", "--points"]) == 0
    got = _contents(out)
    with pcdcodec.open(path) as rec:
        sets = rec.framesets()
        for cam in cams:
            base = f"/world/{cam.spec.name}"
            assert "Pinhole:image_from_camera" in got[base]["columns"]
            transform = got[base]["batches"]
            translations = [
                b.column("Transform3D:translation").to_pylist()
                for b in transform
                if "Transform3D:translation" in b.schema.names
            ]
            assert np.allclose(np.asarray(translations[0][0]).reshape(-1), cam.pose[:3, 3])
            col = rec.camera_names.index(cam.spec.name)
            in_sets = [i for i in range(len(sets)) if sets.matches[i, col] >= 0]
            assert sorted(got[f"{base}/image/depth"]["frames"]) == in_sets
            assert sorted(got[f"{base}/points"]["frames"]) == in_sets
            assert (f"{base}/image/rgb" in got) == (cam.colors is not None)
            # Each camera's depth lossless; its color packets as recorded, up to its last frame
            # shown.
            frames = rec.frames(cam.spec.name)
            logged = _logged_depths(got[f"{base}/image/depth"])
            for k in in_sets:
                frame = sets[k].frames[cam.spec.name]
                assert np.array_equal(logged[k], frame.depth)
            if cam.colors is not None:
                last = max(sets[k].frames[cam.spec.name].timestamp_ns for k in in_sets)
                packets = [p.data for p in frames.packets() if p.pts <= last]
                rgb = got[f"{base}/image/rgb"]["batches"]
                samples = [
                    blob for b in rgb if "VideoStream:sample" in b.schema.names
                    for blob in _blobs(b, "VideoStream:sample")
                ]  # fmt: skip
                assert samples == packets
        # The fused cloud of each set: every camera's thinned points moved by its rig pose.
        fused = got["/world/fused"]
        assert sorted(fused["frames"]) == list(range(len(sets)))
        k = next(i for i in range(len(sets)) if len(sets[i].missing) < len(cams) - 1)
        frameset = sets[k]
        expected = []
        for cam in cams:
            frame = frameset.frames[cam.spec.name]
            if frame is None:
                continue
            depth = frame.depth[::4, ::4]
            v, u = np.nonzero(depth > 0)
            z = depth[v, u] / cam.spec.depth_scale
            intr = cam.spec.intrinsics
            x = (u * 4 - intr.cx) * z / intr.fx
            y = (v * 4 - intr.cy) * z / intr.fy
            own = np.stack([x, y, z], axis=1).astype(np.float32).astype(np.float64)
            expected.append(own @ cam.pose[:3, :3].T + cam.pose[:3, 3])
        rows = [
            (f, p)
            for b in fused["batches"]
            for f, p in zip(
                b.column("frame").to_pylist(),
                b.column("Points3D:positions").to_pylist(),
                strict=True,
            )
        ]
        logged = np.asarray(next(p for f, p in rows if f == k), np.float64)
        want = np.concatenate(expected)
        assert logged.shape == want.shape
        assert np.abs(logged - want).max() < 1e-5  # float32 in Rerun's store


def test_write_rig_folder_and_write_folder_of_a_rig(
    rig: tuple[Path, list[Cam]], tmp_path: Path
) -> None:
    from pcdcodec.datasets import write_folder, write_rig_folder

    path, cams = rig
    seen: list[int] = []
    with pcdcodec.open(path) as rec:
        counts = write_rig_folder(rec, tmp_path / "f", progress=seen.append)
        with pytest.raises(pcdcodec.InputError, match="write_rig_folder"):
            write_folder(rec, tmp_path / "g")
        with pytest.raises(pcdcodec.InputError, match="not empty"):
            write_rig_folder(rec, tmp_path / "f")
    assert counts == {c.spec.name: len(c.times) for c in cams}
    assert seen == list(range(1, sum(counts.values()) + 1))
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == [
        "head", "rig.json", "side", "wrist",
    ]  # fmt: skip


def test_view_open3d_plays_each_frame_sets_fused_cloud(
    rig: tuple[Path, list[Cam]], monkeypatch: pytest.MonkeyPatch
) -> None:
    import open3d as o3d

    from pcdcodec.viewer import view_open3d

    path, _ = rig
    shown: list[int] = []

    class Visualizer:
        def create_window(self, **_: Any) -> bool:
            return True

        def add_geometry(self, cloud: Any) -> None:
            self.cloud = cloud
            shown.append(len(cloud.points))

        def update_geometry(self, cloud: Any) -> None:
            shown.append(len(cloud.points))

        def poll_events(self) -> bool:
            return True

        def update_renderer(self) -> None:
            pass

        def destroy_window(self) -> None:
            pass

    monkeypatch.setattr(o3d.visualization, "Visualizer", Visualizer)
    view_open3d(path, fps=1000.0, every=2)
    with pcdcodec.open(path) as rec:
        sets = rec.framesets()
        assert shown == [len(sets[i].to_points()[0]) for i in range(0, len(sets), 2)]


def test_export_of_a_rig_with_poses_and_clouds(tmp_path: Path) -> None:
    """Frames with a pose place the rig in world on /tf (one tree: world -> rig -> camera);
    clouds go under each camera's namespace, in its frame."""
    from rosbags.highlevel import AnyReader

    from pcdcodec.geometry.transform import quaternion_to_matrix

    cams = _cameras()[::2]  # head and side
    path = tmp_path / "posed.pcdc"
    rig_in_world = [np.eye(4) for _ in range(3)]
    for k, m in enumerate(rig_in_world):
        m[:3, :3] = _rot(2, 10.0 * k)[:3, :3]
        m[:3, 3] = [0.5 * k, 0.0, 1.0]
    with RigWriter(path, [c.spec for c in cams]) as w:
        for k in range(3):
            for cam in cams:
                color = None if cam.colors is None else cam.colors[k]
                pose = rig_in_world[k] @ cam.pose  # the camera's pose in world
                w.write(cam.spec.name, color, cam.depths[k], cam.times[k], pose=pose)
    bag = tmp_path / "posed.bag"
    summary = pcdcodec.export_bag(path, bag, cloud=True, images=False, camera_info=False)
    assert set(summary["topics"]) == {
        "/tf_static", "/tf", "/head/depth_registered/points", "/side/depth_registered/points",
    }  # fmt: skip
    tf: list[tuple[int, str, str, np.ndarray[Any, Any]]] = []
    clouds: dict[str, list[tuple[str, int]]] = {}
    with AnyReader([bag]) as reader:
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/tf":
                for t in msg.transforms:
                    r, v = t.transform.rotation, t.transform.translation
                    m = np.eye(4)
                    m[:3, :3] = quaternion_to_matrix((r.x, r.y, r.z, r.w))
                    m[:3, 3] = [v.x, v.y, v.z]
                    tf.append((stamp, t.header.frame_id, t.child_frame_id, m))
            elif conn.topic.endswith("/points"):
                clouds.setdefault(conn.topic, []).append((msg.header.frame_id, msg.width))
    assert len(tf) == 6  # a sample per frame of each camera
    times = {t: k for cam in cams for k, t in enumerate(cam.times)}
    for stamp, parent, child, m in tf:
        assert (parent, child) == ("world", "rig")
        assert np.allclose(m, rig_in_world[times[stamp]], atol=1e-9)
    assert clouds["/head/depth_registered/points"] == [("head", 640)] * 3
    assert [f for f, _ in clouds["/side/depth_registered/points"]] == ["side_link"] * 3


def test_recover_and_join_of_rig_mutants_give_right_frames_or_pcdcodec_errors(
    tmp_path: Path,
) -> None:
    """Seeded mutants of a rig's file (bytes changed, or whole messages removed, swapped,
    retimed with every CRC recomputed): recover and join raise only pcdcodec's errors, and
    every frame read from what they write is the clean file's, or an error."""
    from pcdcodec.recording.join import join

    from .recording_fuzz import make_clean, mutate

    clean = make_clean("rig", tmp_path)
    outcomes: dict[str, int] = {}
    for case in range(60):
        data, what = mutate(clean, 4021, case)
        mutant = tmp_path / "mutant.pcdc"
        mutant.write_bytes(data)
        out = tmp_path / "out.pcdc"
        for step in ("recover", "join"):
            try:
                if step == "recover":
                    pcdcodec.recover(mutant, out, overwrite=True)
                else:
                    join([mutant], out, overwrite=True)
            except pcdcodec.PcdcodecError:
                outcomes[f"{step} refused"] = outcomes.get(f"{step} refused", 0) + 1
                continue
            outcomes[f"{step} wrote"] = outcomes.get(f"{step} wrote", 0) + 1
            try:
                rec = pcdcodec.open(out)
            except pcdcodec.PcdcodecError:
                continue
            with rec:
                for name in rec.camera_names:
                    frames = rec.frames(name)
                    for k in range(len(frames)):
                        try:
                            frame = frames[k]
                        except pcdcodec.PcdcodecError:
                            continue
                        want = clean.frames.get((name, int(frame.timestamp_ns)))
                        assert want is not None, (what, step, name, k)
                        assert np.array_equal(frame.depth, want[1]), (what, step, name, k)
    assert outcomes.get("recover wrote", 0) >= 10
    assert outcomes.get("recover refused", 0) + outcomes.get("join refused", 0) >= 10


def test_an_exported_rig_bag_encodes_back_as_one_rig(
    rig: tuple[Path, list[Cam]], tmp_path: Path
) -> None:
    """``encode`` reads every namespace of the bag at once, as a camera of one rig (not one
    namespace at a time), each placed where the bag's /tf_static puts it."""
    path, cams = rig
    bag = tmp_path / "rig.bag"
    pcdcodec.export_bag(path, bag, to="rosbag1")
    out = tmp_path / "back.pcdc"
    assert main(["encode", str(bag), "-o", str(out), "-q"]) == 0
    with pcdcodec.open(out) as back:
        assert isinstance(back, RigRecording)
        assert set(back.camera_names) == {c.spec.name for c in cams}
        for cam in cams:
            rec = back.frames(cam.spec.name)
            assert list(rec.timestamps) == cam.times
            assert np.allclose(back.rig_poses[cam.spec.name], cam.pose, atol=1e-9)
            for k, frame in enumerate(rec):
                if cam.spec.depth_scale == 1000.0:
                    assert np.array_equal(frame.depth, cam.depths[k])
                else:
                    expected = to_metres(cam.depths[k], cam.spec.depth_scale)
                    assert np.array_equal(frame.depth, expected, equal_nan=True)
