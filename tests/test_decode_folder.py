"""What `decode` writes keeps what the recording holds: each image's own time, the poses in the
input's layout, and clouds at the precision they are made in."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import DecodeError, InputError
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.cli import main
from pcdcodec.datasets import open_folder, sample_dir
from pcdcodec.recording import _index as fmt
from pcdcodec.recording.rewrite import positions, rewrite, with_data
from pcdcodec.sources.poses import POSE_LAYOUT_KEY, seconds_text


def _ns(text: str) -> int:
    whole, _, frac = text.partition(".")
    return int(whole) * 1_000_000_000 + int(frac.ljust(9, "0"))


def _listed(path: Path) -> list[tuple[str, str]]:
    """The (time text, file) rows of a TUM list."""
    rows = []
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            parts = line.split()
            rows.append((parts[0], parts[1]))
    return rows


def _associated(root: Path, n: int) -> list[list[str]]:
    """The first ``n`` rows of a TUM folder's associations.txt (rgb time, file, depth time,
    file), the frames its reader gives."""
    rows = [
        line.split()
        for line in (root / "associations.txt").read_text().splitlines()
        if line.strip() and not line.startswith("#")
    ]
    return rows[:n]


def _decode(rec: Path, out: Path, *extra: str) -> None:
    assert main(["decode", str(rec), "-o", str(out), "-q", *extra]) == 0


def _tum_round_trip(root: Path, tmp_path: Path, frames: int, **camera: Any) -> None:
    rec = tmp_path / "tum.pcdc"
    pcdcodec.encode(root, rec, max_frames=frames, **camera)
    with pcdcodec.open(rec) as r:
        assert r.metadata[POSE_LAYOUT_KEY] == "tum"
        recorded = list(r)
    rows = _associated(root, frames)
    # The recording keeps each image's own stamp: TUM's depth is 10 to 40 us after its color.
    assert [f.color_timestamp_ns for f in recorded] == [_ns(r[0]) for r in rows]
    assert [f.depth_timestamp_ns for f in recorded] == [_ns(r[2]) for r in rows]
    assert any(f.depth_timestamp_ns != f.timestamp_ns for f in recorded)
    out = tmp_path / "decoded"
    _decode(rec, out)
    # rgb.txt and depth.txt carry the input's own stamps, character for character.
    assert [t for t, _ in _listed(out / "rgb.txt")] == [r[0] for r in rows]
    assert [t for t, _ in _listed(out / "depth.txt")] == [r[2] for r in rows]
    # The poses come back as groundtruth.txt, at the depth stamps they were taken at.
    assert [t for t, _ in _listed(out / "groundtruth.txt")] == [r[2] for r in rows]
    again = open_folder(out)
    assert again.metadata[POSE_LAYOUT_KEY] == "tum"
    decoded = list(again)
    assert len(decoded) == frames
    for a, b in zip(decoded, recorded, strict=True):
        assert a.timestamp_ns == b.timestamp_ns
        assert a.color_timestamp_ns == b.color_timestamp_ns
        assert a.depth_timestamp_ns == b.depth_timestamp_ns
        np.testing.assert_array_equal(a.depth, b.depth)
        assert a.pose is not None
        assert b.pose is not None
        # Written as a quaternion, as TUM's file holds them: equal to float64 rounding.
        np.testing.assert_allclose(a.pose, b.pose, rtol=0, atol=1e-12)


def test_tum_sample_decodes_with_its_own_stamps_and_poses(tmp_path: Path) -> None:
    _tum_round_trip(sample_dir(), tmp_path, 15)


@pytest.mark.skipif(not SEQUENCES["tum_fr1_rpy"].present, reason="TUM fr1_rpy is not present")
def test_tum_fr1_rpy_decodes_with_its_own_stamps_and_poses(tmp_path: Path) -> None:
    seq = SEQUENCES["tum_fr1_rpy"]
    _tum_round_trip(seq.root, tmp_path, 20, intrinsics=seq.camera)


def _seven_scenes_folder(tmp_path: Path) -> Path:
    """A 7-Scenes folder: the real one's first frames when present, else one made from the
    sample in 7-Scenes' names, with pose files (one frame without tracking: -inf)."""
    root = tmp_path / "seven"
    real = SEQUENCES["7scenes_redkitchen"]
    if real.present:

        def later(_: str, names: list[str]) -> list[str]:
            return [n for n in names if n.startswith("frame-") and int(n[6:12]) >= 8]

        shutil.copytree(real.root, root, ignore=later)
        return root
    for sub in ("rgb", "depth", "pose"):
        (root / sub).mkdir(parents=True)
    src = sorted((sample_dir() / "depth").glob("*.png"))[:5]
    colors = sorted((sample_dir() / "rgb").glob("*.png"))[:5]
    rng = np.random.default_rng(7)
    for i, (d, c) in enumerate(zip(src, colors, strict=True)):
        shutil.copy(d, root / "depth" / f"frame-{i:06d}.depth.png")
        shutil.copy(c, root / "rgb" / f"frame-{i:06d}.color.png")
        q = rng.normal(size=4)
        pose = pcdcodec.geometry.transform.rigid_from_quaternion(rng.normal(size=3), q)
        text = "\n".join(" ".join(f"{v:.8e}" for v in row) for row in pose)
        if i == 3:
            text = "\n".join(" ".join(["-inf"] * 4) for _ in range(4))
        (root / "pose" / f"frame-{i:06d}.pose.txt").write_text(text + "\n")
    (root / "camera-intrinsics.txt").write_text("585 0 320\n0 585 240\n0 0 1\n")
    return root


def test_7scenes_poses_decode_as_pose_files(tmp_path: Path) -> None:
    root = _seven_scenes_folder(tmp_path)
    rec = tmp_path / "seven.pcdc"
    pcdcodec.encode(root, rec, depth_scale=1000.0)
    with pcdcodec.open(rec) as r:
        assert r.metadata[POSE_LAYOUT_KEY] == "7scenes"
        recorded = list(r)
    out = tmp_path / "decoded"
    _decode(rec, out)
    assert not (out / "groundtruth.txt").exists()
    names = sorted(p.name for p in (out / "pose").iterdir())
    want = [f"frame-{i:06d}.pose.txt" for i, f in enumerate(recorded) if f.pose is not None]
    assert names == want
    assert (out / "depth" / "frame-000000.depth.png").is_file()
    again = open_folder(out)
    assert again.metadata[POSE_LAYOUT_KEY] == "7scenes"
    decoded = list(again)
    assert len(decoded) == len(recorded)
    for a, b in zip(decoded, recorded, strict=True):
        assert a.timestamp_ns == b.timestamp_ns
        np.testing.assert_array_equal(a.depth, b.depth)
        if b.pose is None:
            assert a.pose is None
        else:
            assert a.pose is not None
            np.testing.assert_array_equal(a.pose, b.pose)  # the matrix, bit for bit
    # 7-Scenes stamps nothing: each image's time is the frame's.
    assert all(f.depth_timestamp_ns == f.timestamp_ns for f in recorded)
    assert [t for t, _ in _listed(out / "depth.txt")] == [
        seconds_text(f.timestamp_ns) for f in recorded
    ]


def _flat_seven_scenes(tmp_path: Path, real: bool) -> Path:
    """7-Scenes as Microsoft ships it, flat: ``frame-NNNNNN.color.*``, ``.depth.png`` and
    ``.pose.txt`` side by side, from the real redkitchen's first frames or from the sample;
    frame 3 untracked (its pose ``-inf``)."""
    root = tmp_path / "flat"
    root.mkdir()
    if real:
        seq = SEQUENCES["7scenes_redkitchen"]
        if not seq.present:
            pytest.skip("7-Scenes redkitchen is not present")
        for i in range(6):
            name = f"frame-{i:06d}"
            for sub, suffix in (("depth", ".depth.png"), ("pose", ".pose.txt")):
                shutil.copy(seq.root / sub / f"{name}{suffix}", root / f"{name}{suffix}")
            (color,) = (seq.root / "rgb").glob(f"{name}.color.*")
            shutil.copy(color, root / color.name)
        shutil.copy(seq.root / "camera-intrinsics.txt", root / "camera-intrinsics.txt")
    else:
        depths = sorted((sample_dir() / "depth").glob("*.png"))[:6]
        colors = sorted((sample_dir() / "rgb").glob("*.png"))[:6]
        rng = np.random.default_rng(11)
        for i, (d, c) in enumerate(zip(depths, colors, strict=True)):
            shutil.copy(d, root / f"frame-{i:06d}.depth.png")
            shutil.copy(c, root / f"frame-{i:06d}.color.png")
            pose = pcdcodec.geometry.transform.rigid_from_quaternion(
                rng.normal(size=3), rng.normal(size=4)
            )
            text = "\n".join("\t".join(f"{v:.17e}" for v in row) for row in pose)
            (root / f"frame-{i:06d}.pose.txt").write_text(text + "\n")
        (root / "camera-intrinsics.txt").write_text("585 0 320\n0 585 240\n0 0 1\n")
    (root / "frame-000003.pose.txt").write_text("\n".join(["-inf -inf -inf -inf"] * 4) + "\n")
    (root / "notes.txt").write_text("not a frame\n")
    return root


@pytest.mark.parametrize("real", [False, True], ids=["sample", "redkitchen"])
def test_flat_7scenes_poses_are_read_and_decode_as_pose_files(tmp_path: Path, real: bool) -> None:
    root = _flat_seven_scenes(tmp_path, real)
    files = [root / f"frame-{i:06d}.pose.txt" for i in range(6)]
    given = [np.loadtxt(f, dtype=np.float64) for f in files]
    src = open_folder(root)
    assert src.metadata[POSE_LAYOUT_KEY] == "7scenes"
    assert src.depth_scale == 1000.0
    # The pose files are read, so not left out; the folder's other file is.
    assert [s.name for s in src.left_out] == ["notes.txt"]
    rec = tmp_path / "flat.pcdc"
    pcdcodec.encode(root, rec)
    with pcdcodec.open(rec) as r:
        assert r.metadata[POSE_LAYOUT_KEY] == "7scenes"
        recorded = list(r)
    assert len(recorded) == 6
    for i, (f, m) in enumerate(zip(recorded, given, strict=True)):
        if i == 3:
            assert f.pose is None  # untracked
        else:
            assert f.pose is not None
            np.testing.assert_array_equal(f.pose, m)  # the file's matrix, bit for bit
    out = tmp_path / "decoded"
    _decode(rec, out)
    names = sorted(p.name for p in (out / "pose").iterdir())
    assert names == [f.name for i, f in enumerate(files) if i != 3]
    for name in names:
        written = np.loadtxt(out / "pose" / name, dtype=np.float64)
        original = np.loadtxt(root / name, dtype=np.float64)
        assert written.tobytes() == original.tobytes()
    decoded = list(open_folder(out))
    for a, b in zip(decoded, recorded, strict=True):
        np.testing.assert_array_equal(a.depth, b.depth)
        if b.pose is None:
            assert a.pose is None
        else:
            assert a.pose is not None
            assert a.pose.tobytes() == b.pose.tobytes()


def test_poses_of_a_recording_that_names_no_layout_go_to_groundtruth(tmp_path: Path) -> None:
    # Recordings of earlier versions, and poses handed to write(), name no layout.
    rec = tmp_path / "posed.pcdc"
    frames = list(open_folder(sample_dir(), max_frames=4))
    with pcdcodec.open(rec, "w", intrinsics=SEQUENCES["sample"].camera, depth_scale=5000.0) as w:
        for f in frames:
            w.write(f.color, f.depth, f.timestamp_ns, pose=f.pose)
    out = tmp_path / "decoded"
    _decode(rec, out)
    rows = _listed(out / "groundtruth.txt")
    assert len(rows) == 4
    again = list(open_folder(out))
    for a, b in zip(again, frames, strict=True):
        assert a.pose is not None
        assert b.pose is not None
        np.testing.assert_allclose(a.pose, b.pose, rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="pose_layout must be one of"):
        pcdcodec.datasets.write_folder(again, tmp_path / "x", pose_layout="kitti")


def _stamped(tmp_path: Path, name: str = "stamped.pcdc", **options: Any) -> Path:
    path = tmp_path / name
    frames = list(open_folder(sample_dir(), max_frames=3))
    with pcdcodec.open(
        path, "w", intrinsics=SEQUENCES["sample"].camera, depth_scale=5000.0, **options
    ) as w:
        for k, f in enumerate(frames):
            t = 1_000_000_000 + k * 33_000_000
            color = f.color if w.color_codec is not None else None
            w.write(color, f.depth, t, color_timestamp=t - 7_000 * k, depth_timestamp=t + 36_000)
    return path


def test_writer_keeps_each_images_own_time(tmp_path: Path) -> None:
    with pcdcodec.open(_stamped(tmp_path)) as r:
        frames = list(r)
        assert r.verify().ok
    for k, f in enumerate(frames):
        t = 1_000_000_000 + k * 33_000_000
        assert f.timestamp_ns == t
        assert f.color_timestamp_ns == t - 7_000 * k
        assert f.depth_timestamp_ns == t + 36_000
    # Depth only: no color time.
    with pcdcodec.open(_stamped(tmp_path, "depth.pcdc", color=None)) as r:
        f = r[1]
        assert f.color_timestamp_ns is None
        assert f.depth_timestamp_ns == 1_033_036_000
    camera = SEQUENCES["sample"].camera
    with (
        pytest.raises(InputError, match="depth_timestamp -1 ns is outside"),
        pcdcodec.open(tmp_path / "bad.pcdc", "w", intrinsics=camera) as w,
    ):
        w.write(None, np.zeros((480, 640), np.uint16), 5, depth_timestamp=-1)


def test_frames_stamped_as_the_frame_write_no_stamps(tmp_path: Path) -> None:
    # What every input but TUM lists gives: the file is as earlier versions wrote it.
    path = tmp_path / "plain.pcdc"
    frames = list(open_folder(sample_dir(), max_frames=2))
    with pcdcodec.open(path, "w", intrinsics=SEQUENCES["sample"].camera, depth_scale=5000.0) as w:
        for f in frames:
            t = f.timestamp_ns
            w.write(f.color, f.depth, t, color_timestamp=t, depth_timestamp=t)
    with pcdcodec.open(path) as r:
        assert r.index.channel(fmt.TOPIC_STAMPS) is None
        assert "stamps" not in r.index.metadata[fmt.SEAL_NAME]
        assert all(f.depth_timestamp_ns == f.timestamp_ns for f in r)


def test_changed_or_added_stamps_are_an_error(tmp_path: Path) -> None:
    src = _stamped(tmp_path)

    def changed(messages: list[Any]) -> list[Any]:
        k = positions(messages, fmt.TOPIC_STAMPS)[1]
        color, depth = fmt.STAMPS_RECORD.unpack(messages[k].data)
        messages[k] = with_data(messages[k], fmt.STAMPS_RECORD.pack(color, depth + 1))
        return messages

    bad = tmp_path / "changed.pcdc"
    rewrite(src, bad, changed)
    with pcdcodec.open(bad) as r:
        with pytest.raises(DecodeError, match="do not match the seal"):
            r[0]
        report = r.verify()
    assert [e for e in report.errors if "/camera/stamps" in e] == [
        f"{str(bad)!r}: the /camera/stamps messages (each image's own time) do not match the "
        "seal (sealed 3, found 3): they were changed, added or removed"
    ]

    def dropped(messages: list[Any]) -> list[Any]:
        k = positions(messages, fmt.TOPIC_STAMPS)[2]
        return messages[:k] + messages[k + 1 :]

    rewrite(src, tmp_path / "dropped.pcdc", dropped)
    with (
        pcdcodec.open(tmp_path / "dropped.pcdc") as r,
        pytest.raises(DecodeError, match=r"/camera/stamps messages"),
    ):
        list(r)


def test_frame_equality_counts_each_images_time() -> None:
    depth = np.zeros((2, 2), np.uint16)
    a = pcdcodec.Frame(None, depth, 5)
    assert a.depth_timestamp_ns == 5
    assert a.color_timestamp_ns is None
    assert a == pcdcodec.Frame(None, depth, 5, depth_timestamp_ns=5)
    assert a != pcdcodec.Frame(None, depth, 5, depth_timestamp_ns=6)
    assert "depth_timestamp_ns=6" in repr(pcdcodec.Frame(None, depth, 5, depth_timestamp_ns=6))
