"""Recordings of several cameras (format version 3): writing, reading, matching and fusing."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import CameraIntrinsics, DecodeError, InputError, Projector
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.recording import CameraSpec, RigRecording, RigWriter
from pcdcodec.recording.reader import Recording, SeveralCamerasError
from pcdcodec.recording.rig_reader import match_times

from .conftest import load_colors, load_depths

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


def _cameras() -> list[Cam]:
    """Three cameras with different sizes, intrinsics, depth scales, rates and start times,
    from the real sequences when they are present (else from the bundled sample)."""
    tum = SEQUENCES["sample"].camera
    head_d = load_depths("sample", 9)
    head_c = load_colors("sample", 9)
    pose_wrist = _rot(1, 30.0)
    pose_wrist[:3, 3] = [0.25, -0.1, 0.05]
    pose_side = _rot(0, -12.0) @ _rot(2, 90.0)
    pose_side[:3, 3] = [-0.4, 0.3, 0.2]
    if SEQUENCES["realsense_d435"].present:
        seq = SEQUENCES["realsense_d435"]
        wrist_d, wrist_c = load_depths(seq.name, 5), load_colors(seq.name, 5)
        wrist_cam, wrist_scale = seq.camera, seq.depth_scale
    else:  # a crop of the sample: other intrinsics and size, another declared scale
        wrist_d = [d[100:340, 200:520].copy() for d in head_d[:5]]
        wrist_c = [c[100:340, 200:520].copy() for c in head_c[:5]]
        wrist_cam = CameraIntrinsics(320, 240, 525.0, 525.0, 119.5, 139.5)
        wrist_scale = 1000.0
    if SEQUENCES["7scenes_redkitchen"].present:
        seq = SEQUENCES["7scenes_redkitchen"]
        side_d = load_depths(seq.name, 4)
        side_cam, side_scale = seq.camera, seq.depth_scale
    else:
        side_d = [d[::2, ::2].copy() for d in head_d[:4]]
        side_cam = CameraIntrinsics(320, 240, 262.5, 262.5, 159.75, 119.75)
        side_scale = 2500.0
    return [
        Cam(
            CameraSpec("head", tum, 5000.0, fps=30.0),
            head_d,
            head_c,
            [1_000 * _MS + k * 33_333_333 for k in range(len(head_d))],
        ),
        Cam(
            CameraSpec(
                "wrist", wrist_cam, wrist_scale, fps=15.0, depth="jpegxl", rig_pose=pose_wrist
            ),
            wrist_d,
            wrist_c,
            [1_013 * _MS + k * 66_666_667 for k in range(len(wrist_d))],
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
            [960 * _MS + k * 100 * _MS for k in range(len(side_d))],
        ),
    ]


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Cam]]:
    cams = _cameras()
    path = tmp_path_factory.mktemp("rig") / "rig.pcdc"
    # Frames of all cameras in the order they happened, as a live rig hands them in.
    events = sorted((t, c, k) for c, cam in enumerate(cams) for k, t in enumerate(cam.times))
    with pcdcodec.open(path, "w", cameras=[c.spec for c in cams], metadata={"site": "lab"}) as w:
        assert isinstance(w, RigWriter)
        for t, c, k in events:
            cam = cams[c]
            color = None if cam.colors is None else cam.colors[k]
            w.write(cam.spec.name, color, cam.depths[k], t)
    return path, cams


def test_every_camera_reads_back_bit_exact(rig: tuple[Path, list[Cam]]) -> None:
    path, cams = rig
    with pcdcodec.open(path) as rec:
        assert isinstance(rec, RigRecording)
        assert rec.camera_names == ["head", "wrist", "side"]
        assert rec.metadata == {"site": "lab"}
        assert rec.format_version == 3
        for cam in cams:
            info = rec.cameras[cam.spec.name]
            assert info.intrinsics == cam.spec.intrinsics
            assert info.depth_scale == cam.spec.depth_scale
            assert info.fps == cam.spec.fps
            expected_pose = np.eye(4) if cam.spec.rig_pose is None else cam.spec.rig_pose
            assert np.array_equal(info.rig_pose, expected_pose)
            assert info.frame_id == (cam.spec.frame_id or cam.spec.name)
            frames = rec.frames(camera=cam.spec.name)
            assert len(frames) == len(cam.depths)
            assert frames.timestamps.tolist() == cam.times
            for k, frame in enumerate(frames):
                assert frame.depth.dtype == np.uint16
                assert np.array_equal(frame.depth, cam.depths[k])
                if cam.colors is None:
                    assert frame.color is None
                else:
                    assert frame.color is not None
                    assert frame.color.shape == cam.colors[k].shape
                    # h264 at its default quality: close, not exact.
                    err = np.abs(frame.color.astype(int) - cam.colors[k].astype(int)).mean()
                    assert err < 6.0
        assert rec.verify().ok


def test_random_access_per_camera(rig: tuple[Path, list[Cam]]) -> None:
    path, cams = rig
    with pcdcodec.open(path) as rec:
        wrist = rec.frames("wrist")
        for k in (3, 0, 4, 1):
            assert np.array_equal(wrist[k].depth, cams[1].depths[k])


def test_framesets_match_as_the_stamps_say(rig: tuple[Path, list[Cam]]) -> None:
    path, cams = rig
    with pcdcodec.open(path) as rec:
        sets = rec.framesets()
        ref = np.asarray(cams[0].times)
        tol = round(0.5 / 30.0 * 1e9)
        assert sets.tolerance_ns == tol
        assert len(sets) == len(ref)
        # Brute force: each set takes the frame nearest in time within the tolerance.
        for c, cam in enumerate(cams[1:], start=1):
            other = np.asarray(cam.times)
            for k, t in enumerate(ref):
                d = np.abs(other - t)
                want = int(np.argmin(d)) if d.min() <= tol else -1
                assert sets.matches[k, c] == want, (cam.spec.name, k)
        assert sets.timestamps.tolist() == cams[0].times
        missing = [s.missing for s in sets]
        assert sets.incomplete == sum(1 for m in missing if m)
        assert any("side" in m for m in missing)
        first = sets[0]
        assert first.timestamp_ns == cams[0].times[0]
        for name, frame in first.frames.items():
            if frame is not None:
                col = rec.camera_names.index(name)
                k = int(sets.matches[0, col])
                assert frame.timestamp_ns == rec.frames(name).timestamps[k]
        # A wider tolerance fills more sets; the wrist as the reference drives the sets.
        wide = rec.framesets(tolerance=0.2)
        assert wide.incomplete <= sets.incomplete
        by_wrist = rec.framesets(reference="wrist")
        assert len(by_wrist) == len(cams[1].times)
        assert by_wrist.matches[:, 1].tolist() == list(range(len(cams[1].times)))


def test_fused_cloud_is_each_camera_transformed(rig: tuple[Path, list[Cam]]) -> None:
    path, cams = rig
    with pcdcodec.open(path) as rec:
        sets = rec.framesets(tolerance=0.1)
        full = next(s for s in sets if s.complete)
        points, colors, slices = full.to_points()
        assert colors is not None
        assert colors.shape == points.shape
        total = 0
        for cam in cams:
            frame = full.frames[cam.spec.name]
            assert frame is not None
            projector = Projector(cam.spec.intrinsics, cam.spec.depth_scale)
            own, own_colors = projector.to_points(frame.depth, frame.color)
            pose = np.eye(4) if cam.spec.rig_pose is None else cam.spec.rig_pose
            expected = own.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
            part = points[slices[cam.spec.name]]
            assert part.shape == expected.shape
            assert np.abs(part.astype(np.float64) - expected).max() <= 1e-6
            if own_colors is None:
                assert not colors[slices[cam.spec.name]].any()  # black
            else:
                assert np.array_equal(colors[slices[cam.spec.name]], own_colors)
            total += len(expected)
        assert len(points) == total
        legacy = full.to_point_cloud()
        assert np.allclose(np.asarray(legacy.points), points, atol=0)
        assert np.allclose(np.asarray(legacy.colors) * 255.0, colors, atol=1e-9)
        tensor = full.to_point_cloud(tensor=True)
        assert np.array_equal(tensor.point.positions.numpy(), points)


def test_a_one_camera_reader_refuses_a_rig_clearly(rig: tuple[Path, list[Cam]]) -> None:
    path, _ = rig
    with pytest.raises(SeveralCamerasError, match=r"holds 3 cameras \(head, wrist, side\)"):
        Recording(path)
    with pcdcodec.open(path) as rec, pytest.raises(InputError, match="pass camera="):
        rec.frames()
    with pcdcodec.open(path) as rec, pytest.raises(InputError, match="no camera 'tail'"):
        rec.frames("tail")


def test_changed_rig_pose_is_refused(rig: tuple[Path, list[Cam]], tmp_path: Path) -> None:
    path, _ = rig
    data = bytearray(path.read_bytes())
    at = data.find(b"[[0.8660254037844387")  # the wrist's rotation, first entry
    assert at > 0
    data[at + 3] = ord("7")
    bad = tmp_path / "bad.pcdc"
    bad.write_bytes(bytes(data))
    with pytest.raises(DecodeError, match="does not match its digest"):
        pcdcodec.open(bad)


def test_cameras_write_in_any_order_and_a_killed_rig_keeps_its_frames(tmp_path: Path) -> None:
    depths = load_depths("sample", 4)
    cam = SEQUENCES["sample"].camera
    specs = [CameraSpec("a", cam, 5000.0, color=None), CameraSpec("b", cam, 5000.0, color=None)]
    path = tmp_path / "killed.pcdc"
    w = RigWriter(path, specs)
    # Each camera's times increase; across cameras any order.
    w.write("b", None, depths[0], 50 * _MS)
    w.write("a", None, depths[1], 10 * _MS)
    w.write("a", None, depths[2], 20 * _MS)
    w.write("b", None, depths[3], 60 * _MS)
    with pytest.raises(InputError, match="does not increase"):
        w.write("a", None, depths[0], 15 * _MS)
    with pytest.raises(InputError, match="no camera 'c'"):
        w.write("c", None, depths[0], 15 * _MS)
    w.flush()
    assert w.frames_complete == {"a": 2, "b": 2}
    w.abort()  # as if the process died: no seals, no summary
    with pcdcodec.open(path) as rec:
        assert not rec.index.indexed
        assert np.array_equal(rec.frames("a")[1].depth, depths[2])
        assert rec.frames("b").timestamps.tolist() == [50 * _MS, 60 * _MS]
        assert np.array_equal(rec.frames("b")[0].depth, depths[0])


def test_bad_rigs_are_refused(tmp_path: Path) -> None:
    cam = SEQUENCES["sample"].camera
    path = tmp_path / "x.pcdc"
    cases: list[tuple[Any, str]] = [
        ([], "at least one camera"),
        ([CameraSpec("a", cam), CameraSpec("a", cam)], "given more than once"),
        ([CameraSpec("1cam", cam)], "is not a name"),
        ([CameraSpec("a/b", cam)], "is not a name"),
        ([CameraSpec("a", cam, frame_id="x"), CameraSpec("b", cam, frame_id="x")], "must all"),
        ([CameraSpec("rig", cam)], "must all differ"),
        ([CameraSpec("a", cam, rig_pose=np.ones((4, 4)))], "rig_pose"),
        (CameraSpec("a", cam), "list of CameraSpec"),
        (["a"], "expected a CameraSpec"),
    ]
    for cameras, message in cases:
        with pytest.raises(InputError, match=message):
            RigWriter(path, cameras)
        assert not path.exists()  # nothing left behind


def test_match_times_gives_each_frame_to_one_set() -> None:
    ref = np.array([0, 100, 200, 300], np.int64)
    other = np.array([40, 60, 310], np.int64)
    # 40 is nearest to 0 (40) and 100 (60): set 0 takes it; 60 goes to set 1.
    assert match_times(ref, other, 50).tolist() == [0, 1, -1, 2]
    # A single frame wanted by two sets goes to the nearer one.
    assert match_times(ref, np.array([90], np.int64), 200).tolist() == [-1, 0, -1, -1]
    assert match_times(ref, np.zeros(0, np.int64), 50).tolist() == [-1] * 4


def test_one_camera_recordings_are_as_before(tmp_path: Path) -> None:
    depths = load_depths("sample", 2)
    path = tmp_path / "one.pcdc"
    with pcdcodec.open(path, "w", intrinsics=SEQUENCES["sample"].camera, color=None) as w:
        for d in depths:
            w.write(None, d)
    with pcdcodec.open(path) as rec:
        assert type(rec) is Recording
        assert rec.format_version == 1
        meta = rec.index.metadata["pcdcodec"]
        assert "cameras" not in meta
        assert json.loads(meta["metadata_records"]) == []
        assert set(rec.index.times) >= {"/camera/depth", "/camera/frame_digest"}


# -- a killed rig -------------------------------------------------------------------------------

# Two cameras of the sample cut to 160x120, the second at half the rate and 5 ms later. Prints
# "<camera> <k> <complete>" before handing in each frame (complete: that camera's frames whose
# messages were all written by then); in "idle" mode, flushes after the last frame and prints
# "idle", then waits to be killed.
KILLED_RIG = """
import sys, time, pcdcodec
path, mode, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
seq = pcdcodec.load_sample()
i0 = seq.intrinsics
cam = pcdcodec.CameraIntrinsics(160, 120, i0.fx / 4, i0.fy / 4, i0.cx / 4, i0.cy / 4)
frames = [(f.color[::4, ::4].copy(), f.depth[::4, ::4].copy()) for f in seq]
specs = [pcdcodec.CameraSpec("a", cam, seq.depth_scale), pcdcodec.CameraSpec("b", cam, 1000.0)]
with pcdcodec.open(path, "w", cameras=specs) as rig:
    for k in range(count):
        time.sleep(1 / 30)
        color, depth = frames[k % len(frames)]
        print("a", k, rig.frames_complete["a"], flush=True)
        rig.write("a", color, depth, k * 33_000_000)
        if k % 2 == 0:
            print("b", k, rig.frames_complete["b"], flush=True)
            rig.write("b", color, depth, k * 33_000_000 + 5_000_000)
    rig.flush()
    print("idle", flush=True)
    time.sleep(60)
"""


def _kill_rig(
    path: Path, mode: str, count: int, after: float
) -> tuple[dict[str, int], dict[str, int], Any]:
    import os
    import signal
    import subprocess
    import sys
    import time

    proc = subprocess.Popen(
        [sys.executable, "-c", KILLED_RIG, str(path), mode, str(count)],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    lines: list[str] = []
    try:
        lines.append(proc.stdout.readline())
        assert lines[0].split()[0] == "a", lines
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # past the codecs' start-up
            try:
                with pcdcodec.open(path) as rec:
                    if len(rec.frames("a")) >= 1:
                        break
            except pcdcodec.PcdcodecError:
                pass  # not yet a readable file: its first records are still being written
            time.sleep(0.05)
        if mode == "idle":
            while lines[-1].strip() not in ("idle", ""):
                lines.append(proc.stdout.readline())
        time.sleep(after)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    lines += proc.stdout.read().splitlines()
    proc.stdout.close()
    handed = {"a": 0, "b": 0}
    complete = {"a": 0, "b": 0}
    for line in lines:
        parts = line.split()
        if len(parts) == 3:
            handed[parts[0]] += 1
            complete[parts[0]] = int(parts[2])
    return handed, complete, pcdcodec.open(path)


@pytest.mark.parametrize("after", [0.3, 0.7])
def test_sigkill_of_a_recording_rig_loses_only_frames_still_in_flight(
    tmp_path: Path, after: float
) -> None:
    handed, complete, rec = _kill_rig(tmp_path / "k.pcdc", "paced", 10_000, after)
    with rec:
        assert not rec.index.indexed
        assert handed["a"] >= 5
        for name in ("a", "b"):
            readable = len(rec.frames(name))
            # Every frame written before the last one handed in is there; at most the frame
            # being handed in and the camera's queue (in_flight = 4) are lost. On a quiet
            # machine the codecs keep up and that is the frame being handed in.
            assert complete[name] <= readable <= handed[name], (name, handed, complete, readable)
            assert handed[name] - readable <= 1 + 4
        seq = pcdcodec.load_sample()
        for name in ("a", "b"):
            for k, frame in enumerate(rec.frames(name)):
                step = 1 if name == "a" else 2
                assert np.array_equal(frame.depth, seq[(k * step) % len(seq)].depth[::4, ::4])


def test_sigkill_of_an_idle_rig_loses_nothing(tmp_path: Path) -> None:
    handed, _, rec = _kill_rig(tmp_path / "k.pcdc", "idle", 7, 0.02)
    with rec:
        assert handed == {"a": 7, "b": 4}
        assert {n: len(rec.frames(n)) for n in ("a", "b")} == handed


def test_join_takes_parts_where_a_camera_has_no_frames(tmp_path: Path) -> None:
    from pcdcodec.recording.join import join

    depths = load_depths("sample", 6)
    cam = SEQUENCES["sample"].camera
    specs = [CameraSpec("a", cam, 5000.0), CameraSpec("b", cam, 1000.0, color=None)]
    colors = load_colors("sample", 6)
    # Part 1: camera "b" has not started; part 3: "a" has stopped.
    plan = [[("a", 0)], [("a", 1), ("b", 2), ("a", 3)], [("b", 4), ("b", 5)]]
    parts = []
    for p, frames in enumerate(plan):
        path = tmp_path / f"part{p}.pcdc"
        with RigWriter(path, specs) as w:
            for name, k in frames:
                color = colors[k] if name == "a" else None
                w.write(name, color, depths[k], (k + 1) * 33 * _MS)
        parts.append(path)
    out = tmp_path / "joined.pcdc"
    assert join(parts, out) == 6
    with pcdcodec.open(out) as rec:
        assert rec.verify().ok
        got = {n: [int(t) // (33 * _MS) - 1 for t in rec.frames(n).timestamps] for n in "ab"}
        assert got == {"a": [0, 1, 3], "b": [2, 4, 5]}
        for name in "ab":
            for frame, k in zip(rec.frames(name), got[name], strict=True):
                assert np.array_equal(frame.depth, depths[k])


def test_the_writers_chunk_index_is_packed_and_writes_the_same_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pcdcodec.recording import _header

    depths = [d[::4, ::4].copy() for d in load_depths("sample", 10)]
    cam = SEQUENCES["sample"].camera
    small = CameraIntrinsics(160, 120, cam.fx / 4, cam.fy / 4, cam.cx / 4, cam.cy / 4)

    chunks = _header._CHUNK_INDEXES  # where mcap's writer keeps them

    def record(path: Path) -> Any:
        with pcdcodec.open(path, "w", intrinsics=small, color="ffv1", depth="zstd") as w:
            for k in range(40):
                w.write(np.zeros((120, 160, 3), np.uint8) + k, depths[k % 10], k * 33 * _MS)
            store = getattr(w._mcap, chunks)
        return store

    store = record(tmp_path / "packed.pcdc")
    assert isinstance(store, _header.PackedChunkIndexes)
    assert len(store) >= 3 * 40  # a chunk per message: color, depth and digest per frame
    assert store.nbytes == 72 * len(store)  # was about 600 bytes per entry
    monkeypatch.setattr(_header, "_CHUNK_INDEXES", "_not_the_writers")
    plain = record(tmp_path / "plain.pcdc")
    assert not isinstance(plain, _header.PackedChunkIndexes)
    assert (tmp_path / "packed.pcdc").read_bytes() == (tmp_path / "plain.pcdc").read_bytes()


# -- what a review of the rig code found --------------------------------------------------------


def _small_frames(n: int) -> tuple[CameraIntrinsics, float, list[tuple[Any, Any]]]:
    seq = pcdcodec.load_sample(max_frames=n)
    k = SEQUENCES["sample"].camera
    small = CameraIntrinsics(160, 120, k.fx / 4, k.fy / 4, k.cx / 4, k.cy / 4)
    frames = [
        (
            np.ascontiguousarray(np.asarray(f.color)[::4, ::4]),
            np.ascontiguousarray(f.depth[::4, ::4]),
        )
        for f in seq
    ]
    return small, seq.depth_scale, frames


def test_match_times_fills_every_set_a_matching_can() -> None:
    # Two 30 fps cameras half a frame apart: each set has two frames at the tolerance's edge.
    ref = np.arange(300, dtype=np.int64) * 33_333_333
    other = ref + 16_666_666
    matched = match_times(ref, other, round(0.5 / 30 * 1e9))
    assert (matched >= 0).all()
    assert len(set(matched.tolist())) == 300
    # Set 1 takes the frame 60 ms away rather than losing the one set 0 is nearer to.
    assert match_times(np.array([0, 100]), np.array([49, 160]), 70).tolist() == [0, 1]
    # Against every matching of small random cases: the most sets, then the least distance.
    rng = np.random.default_rng(5)
    for _ in range(300):
        ref = np.sort(rng.choice(60, int(rng.integers(0, 6)), replace=False)).astype(np.int64)
        other = np.sort(rng.choice(60, int(rng.integers(0, 6)), replace=False)).astype(np.int64)
        tol = int(rng.integers(0, 25))
        got = match_times(ref, other, tol)
        pairs = [(k, int(j)) for k, j in enumerate(got.tolist()) if j >= 0]
        assert len({j for _, j in pairs}) == len(pairs)
        assert all(abs(int(other[j]) - int(ref[k])) <= tol for k, j in pairs)
        value = (len(pairs), -sum(abs(int(other[j]) - int(ref[k])) for k, j in pairs))

        def best(
            k: int, used: frozenset[int], ref: Any = ref, other: Any = other, tol: int = tol
        ) -> tuple[int, int]:
            if k == len(ref):
                return (0, 0)
            options = [best(k + 1, used)]
            for j in range(len(other)):
                d = abs(int(other[j]) - int(ref[k]))
                if j not in used and d <= tol:
                    filled, dist = best(k + 1, used | {j})
                    options.append((filled + 1, dist - d))
            return max(options)

        assert value == best(0, frozenset())


def _match_times_by_last_frame(
    reference: np.ndarray[Any, Any], other: np.ndarray[Any, Any], tolerance_ns: int
) -> list[int]:
    """The matching of earlier releases, as a reference: set by set, for each frame that may
    still be taken, the best matching so far whose last frame is that one (cubic time)."""
    n, m = len(reference), len(other)
    out = [-1] * n
    if not n or not m:
        return out
    lo = np.searchsorted(other, reference - tolerance_ns, side="left")
    hi = np.searchsorted(other, reference + tolerance_ns, side="right")
    ref, oth = reference.tolist(), other.tolist()
    best: dict[int, tuple[tuple[int, int], Any]] = {-1: ((0, 0), None)}
    for k in range(n):
        a, b = int(lo[k]), int(hi[k])
        folded = [j for j in best if j < a]
        if len(folded) > 1 or (folded and folded[0] != -1):
            keep = max((best[j] for j in folded), key=lambda e: e[0])
            for j in folded:
                del best[j]
            best[-1] = keep
        taken: dict[int, tuple[tuple[int, int], Any]] = {}
        for j in range(a, b):
            prior = [e for u, e in best.items() if u < j]
            (filled, dist), chain = max(prior, key=lambda e: e[0])
            taken[j] = ((filled + 1, dist - abs(oth[j] - ref[k])), (k, j, chain))
        for j, entry in taken.items():
            if j not in best or entry[0] > best[j][0]:
                best[j] = entry
    _, chain = max(best.values(), key=lambda e: e[0])
    while chain is not None:
        k, j, chain = chain
        out[k] = j
    return out


def _matching_value(
    reference: np.ndarray[Any, Any], other: np.ndarray[Any, Any], tol: int, got: list[int]
) -> tuple[int, int]:
    """(sets filled, -summed distance) of a matching, after checking that it is one: each
    frame once, within the tolerance, never crossing."""
    pairs = [(k, j) for k, j in enumerate(got) if j >= 0]
    assert all(pairs[a][1] < pairs[a + 1][1] for a in range(len(pairs) - 1))
    dists = [abs(int(other[j]) - int(reference[k])) for k, j in pairs]
    assert all(d <= tol for d in dists)
    return len(pairs), -sum(dists)


def test_match_times_is_as_good_as_the_matching_by_last_frame() -> None:
    # Random stamps with repeats, crowded windows and tolerances from 0 to past the span.
    rng = np.random.default_rng(11)
    same = 0
    for _ in range(1500):
        span = int(rng.integers(1, 300))
        ref = np.sort(rng.integers(0, span, int(rng.integers(0, 25)))).astype(np.int64)
        other = np.sort(rng.integers(0, span, int(rng.integers(0, 25)))).astype(np.int64)
        tol = int(rng.integers(0, 120))
        want = _match_times_by_last_frame(ref, other, tol)
        got = match_times(ref, other, tol).tolist()
        assert _matching_value(ref, other, tol, got) == _matching_value(ref, other, tol, want), (
            ref.tolist(),
            other.tolist(),
            tol,
        )
        same += got == want
    # Where the best matching is one of several equally good, either may be chosen.
    assert same > 1000


def _matching_steps(n: int) -> int:
    """Lines of pcdcodec's matching run to match two 30 fps cameras of ``n`` frames each
    with the tolerance of a stated 0.01 fps (every frame within tolerance of every other)."""
    import sys

    from pcdcodec.recording import framesets as module

    ref = np.arange(n, dtype=np.int64) * 33_333_333
    other = ref + 5_000_000
    steps = 0

    def trace(frame: Any, event: str, arg: Any) -> Any:
        nonlocal steps
        if frame.f_code.co_filename != module.__file__:
            return None
        steps += 1
        return trace

    previous = sys.gettrace()
    sys.settrace(trace)
    try:
        matched = match_times(ref, other, round(0.5 / 0.01 * 1e9))
    finally:
        sys.settrace(previous)
    assert matched.tolist() == list(range(n))
    return steps


def test_match_times_grows_linearly_with_the_frames() -> None:
    # Counted, not timed: 4x the frames must take less than 8x the steps (cubic took 60x).
    small, large = _matching_steps(50), _matching_steps(200)
    assert large < 8 * small, (small, large)


@pytest.mark.parametrize("which", ["rig_pose", "cameras"])
def test_json_nested_too_deep_in_a_rig_record_is_a_decode_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, which: str
) -> None:
    import types

    import pcdcodec.recording.rig as rigmod

    small, scale, frames = _small_frames(2)
    deep = "[" * 100_000 + "]" * 100_000

    def dumps(value: Any, *args: Any, **kwargs: Any) -> str:
        if which == "rig_pose" and isinstance(value, list) and len(value) == 4:
            return deep
        if which == "cameras" and value == ["a", "b"]:
            return deep
        return json.dumps(value, *args, **kwargs)

    monkeypatch.setattr(rigmod, "json", types.SimpleNamespace(dumps=dumps))
    path = tmp_path / "deep.pcdc"
    specs = [CameraSpec("a", small, scale, color=None), CameraSpec("b", small, scale, color=None)]
    with RigWriter(path, specs) as w:
        w.write("a", None, frames[0][1], 0)
    monkeypatch.undo()
    with pytest.raises(DecodeError, match=r"deep\.pcdc"):
        pcdcodec.open(path)
    with pytest.raises(DecodeError, match=r"deep\.pcdc"):
        pcdcodec.recover(path, tmp_path / "out.pcdc")
    from pcdcodec.recording.join import join

    with pytest.raises(pcdcodec.PcdcodecError, match=r"deep\.pcdc"):
        join([path], tmp_path / "joined.pcdc")


def test_a_camera_starting_after_the_file_broke_writes_nothing(tmp_path: Path) -> None:
    import builtins

    import pcdcodec.recording.writer as writermod

    small, scale, frames = _small_frames(3)

    class DiskFills:
        """A file whose next write after ``fail()`` stops half way with ENOSPC."""

        def __init__(self, f: Any) -> None:
            self.f, self.armed = f, False

        def fail(self) -> None:
            self.armed = True

        def write(self, data: Any) -> int:
            if self.armed:
                self.armed = False
                self.f.write(bytes(data[: len(data) // 2]))
                raise OSError(28, "No space left on device")
            return int(self.f.write(data))

        def __getattr__(self, name: str) -> Any:
            return getattr(self.f, name)

    held: dict[str, DiskFills] = {}

    def opener(*args: Any, **kwargs: Any) -> DiskFills:
        held["f"] = DiskFills(builtins.open(*args, **kwargs))  # noqa: SIM115 - closed by close()
        return held["f"]

    path = tmp_path / "full.pcdc"
    specs = [CameraSpec("a", small, scale, color="ffv1"), CameraSpec("b", small, scale)]
    writermod.open = opener  # type: ignore[attr-defined]  # the writers open files there
    try:
        w = RigWriter(path, specs)
    finally:
        del writermod.open  # type: ignore[attr-defined]
    w.write("a", *frames[0], 0)
    w.flush()
    held["f"].fail()
    w.write("a", *frames[1], 10**8)
    with pytest.raises(OSError, match="No space"):
        w.camera("a").flush()
    held["f"].f.flush()
    size = path.stat().st_size
    with pytest.raises(pcdcodec.PcdcodecError, match="not written further"):
        w.write("b", *frames[0], 0)  # its first frame: channels and calibration
    with pytest.raises(pcdcodec.PcdcodecError, match="left unfinished"):
        w.close()
    assert path.stat().st_size == size  # nothing after the half-written record
    with pcdcodec.open(path) as rec:  # unfinished, not damaged: camera a's first frame reads
        assert rec.index.damaged_at is None
        assert len(rec.frames("a")) == 1
        assert np.array_equal(rec.frames("a")[0].depth, frames[0][1])


def test_join_compares_a_late_camera_between_the_parts_that_have_it(tmp_path: Path) -> None:
    from pcdcodec.recording.join import join
    from pcdcodec.registry import as_codec

    small, scale, frames = _small_frames(2)
    ffv1: Any = type(as_codec("ffv1", "color"))
    specs = [
        CameraSpec("a", small, scale, color=None, depth="png16"),
        CameraSpec("b", small, scale, color="ffv1", depth="png16"),
    ]
    with RigWriter(tmp_path / "p0.pcdc", specs) as w:  # camera b has not started
        w.write("a", None, frames[0][1], 0)
    for p, level in ((1, 1), (2, 3)):  # b's packets from encoders of other set-up bytes
        encoder = ffv1(level=level).encoder(160, 120, 30.0)
        with RigWriter(tmp_path / f"p{p}.pcdc", specs) as w:
            for i, (color, depth) in enumerate(frames):
                t = p * 10**9 + i * 33_333_333
                packets = encoder.encode(color, t)
                w.camera("b").write_encoded(packets, depth, t, extradata=encoder.extradata)
    parts = [tmp_path / f"p{p}.pcdc" for p in range(3)]
    with pytest.raises(InputError, match=r"p2.pcdc' cannot follow .*p1.pcdc': camera 'b'"):
        join(parts, tmp_path / "joined.pcdc")


def test_rig_errors_name_the_record_the_topic_and_the_camera(tmp_path: Path) -> None:
    from pcdcodec.recording.rewrite import read, write

    intr, scale, items = _small_frames(4)
    specs = [
        CameraSpec("head", intr, scale, color="ffv1", depth="zstd"),
        CameraSpec("wrist", intr, scale, color="ffv1", depth="rvl"),
    ]
    path = tmp_path / "rig.pcdc"
    with RigWriter(path, specs) as w:
        for k, (color, depth) in enumerate(items):
            w.write("head", color, depth, 1_000_000_000 + k * 33_000_000)
            w.write("wrist", color, depth, 1_000_000_500 + k * 33_000_000)

    def mutant(name: str, edit: Any) -> Path:
        contents = read(path)
        edit(contents)
        write(contents, tmp_path / name)
        return tmp_path / name

    def no_wrist_seal(c: Any) -> None:
        c.metadata = [(n, m) for n, m in c.metadata if n != "pcdcodec.seal.wrist"]

    with pytest.raises(DecodeError, match=r"seal record 'pcdcodec\.seal\.wrist' is missing"):
        pcdcodec.open(mutant("noseal.pcdc", no_wrist_seal))

    def swap_depth_channels(c: Any) -> None:
        c.channels["/head/depth"], c.channels["/wrist/depth"] = (
            c.channels["/wrist/depth"],
            c.channels["/head/depth"],
        )

    with pytest.raises(
        DecodeError,
        match=r"camera 'head': channel '/head/depth' says codec is \{\"id\": \"rvl\"\}, but the "
        r"'pcdcodec\.camera\.head' record",
    ):
        pcdcodec.open(mutant("swapped.pcdc", swap_depth_channels))

    def duplicate_head_depth(c: Any) -> None:
        k = next(i for i, m in enumerate(c.messages) if m.topic == "/head/depth")
        c.messages.insert(k + 1, c.messages[k])

    with pcdcodec.open(mutant("dup.pcdc", duplicate_head_depth)) as rec:
        errors = rec.verify().errors
    assert "camera 'head': 1 message(s) on '/head/depth' are stored twice" in errors
    assert not [e for e in errors if e.startswith("camera 'wrist'")], errors
    assert sum("summary (index) is unusable" in e for e in errors) == 1, errors

    cut = tmp_path / "cut.pcdc"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size * 2 // 3])
    from pcdcodec.recording.source import RecordingSource

    with pytest.raises(DecodeError, match=r"cut short.*`pcdcodec recover`") as info:
        RecordingSource(cut)
    assert "camera=NAME" not in str(info.value)


def test_framesets_default_tolerance_too_wide_names_the_fps(tmp_path: Path) -> None:
    # At fps 1e-7, half a frame is 5e6 s: the error says where that tolerance came from.
    path = tmp_path / "slow.pcdc"
    depth = load_depths("sample", 1)[0]
    cams = [
        CameraSpec("a", SEQUENCES["sample"].camera, 5000.0, fps=1e-7, color=None, depth="zstd"),
        CameraSpec("b", SEQUENCES["sample"].camera, 5000.0, fps=1e-7, color=None, depth="zstd"),
    ]
    with pcdcodec.open(path, "w", cameras=cams) as w:
        w.write("a", None, depth, 0)
        w.write("b", None, depth, 1_000)
    with pcdcodec.open(path) as rec:
        with pytest.raises(InputError) as err:
            rec.framesets()
        message = str(err.value)
        assert "default tolerance" in message
        assert "camera 'a'" in message
        assert "fps 1e-07" in message
        assert "pass tolerance=" in message
        assert len(rec.framesets(tolerance=0.01)) == 1
        with pytest.raises(InputError, match=r"got 2000000\.0"):
            rec.framesets(tolerance=2e6)
