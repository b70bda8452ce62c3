"""Color digests and the seal: files whose CRCs, offsets and summary are all consistent, but
whose frames or colors are not what was written, are refused or reported, never read wrong.

Each hostile file is a clean recording rewritten with the ``mcap`` library
(``pcdcodec/recording/rewrite.py``), so every CRC and the summary match its new contents.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.cli import main
from pcdcodec.recording import _index as fmt
from pcdcodec.recording.join import join
from pcdcodec.recording.rewrite import (
    Message,
    positions,
    read,
    rewrite,
    with_data,
    without_integrity,
    write,
)

W, H = 64, 48
CAMERA = pcdcodec.CameraIntrinsics(W, H, 52.5, 52.5, 31.5, 23.5)


def frames(n: int = 5, offset: int = 0) -> list[tuple[Any, Any, int]]:
    yy, xx = np.mgrid[0:H, 0:W]
    out = []
    for i in range(offset, offset + n):
        color = np.stack(
            [(xx * 4 + i * 9) % 256, (yy * 5 + i * 7) % 256, ((xx + yy) * 3 + i) % 256], axis=-1
        ).astype(np.uint8)
        depth = (1000 + xx * 7 + yy * 11 + i * 13).astype(np.uint16)
        out.append((color, depth, 1_000_000_000 + i * 33_333_333))
    return out


def record(path: Path, items: list[tuple[Any, Any, int]], color: Any = "ffv1") -> Path:
    with pcdcodec.open(
        path, "w", intrinsics=CAMERA, depth_scale=1000.0, color=color, depth="zstd"
    ) as w:
        for c, d, ts in items:
            w.write(c if color else None, d, ts)
    return path


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Five ffv1 + zstd frames: one keyframe, then frames that depend on the ones before."""
    return record(tmp_path_factory.mktemp("seal") / "clean.pcdc", frames())


@pytest.fixture(scope="module")
def decoded(clean: Path) -> dict[int, tuple[Any, Any]]:
    with pcdcodec.open(clean) as rec:
        return {f.timestamp_ns: (f.color, f.depth) for f in rec}


def hostile(clean: Path, path: Path, edit: Any, **options: Any) -> Path:
    rewrite(clean, path, edit, **options)
    return path


def drop_first_keyframe_marker(ms: list[Message]) -> list[Message]:
    k = positions(ms, fmt.TOPIC_KEYFRAMES)[0]
    return ms[:k] + ms[k + 1 :]


def drop_last_color_packet(ms: list[Message]) -> list[Message]:
    k = positions(ms, fmt.TOPIC_COLOR)[-1]
    return ms[:k] + ms[k + 1 :]


def swap_color_packets(ms: list[Message]) -> list[Message]:
    a, b = positions(ms, fmt.TOPIC_COLOR)[1:3]
    ms[a], ms[b] = ms[b], ms[a]
    return ms


def change_color_byte(ms: list[Message]) -> list[Message]:
    k = positions(ms, fmt.TOPIC_COLOR)[2]
    data = bytearray(ms[k].data)
    data[len(data) * 2 // 3] ^= 0x10
    ms[k] = with_data(ms[k], bytes(data))
    return ms


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.err


def assert_cli_refuses(path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for args in (
        ("info", str(path)),
        ("verify", str(path)),
        ("decode", str(path), "-o", str(tmp_path / "out")),
    ):
        status, err = cli(capsys, *args)
        assert status == 1, args
        assert str(path) in err, args
        assert "Traceback" not in err


def test_a_clean_file_is_sealed_and_verifies(clean: Path) -> None:
    with pcdcodec.open(clean) as rec:
        assert rec.integrity == 1
        assert len(rec) == 5
        assert rec.verify().ok
        seal = rec.index.metadata[fmt.SEAL_NAME]
    assert seal["frames"] == "5"
    assert seal["first_timestamp"] == "1000000000"


def test_removed_first_keyframe_marker_is_refused(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = hostile(clean, tmp_path / "nokey.pcdc", drop_first_keyframe_marker)
    # Every CRC holds: an MCAP reader finds nothing wrong, and earlier pcdcodec read 0 frames.
    with pytest.raises(pcdcodec.DecodeError, match=r"nokey\.pcdc.*sealed.*keyframes"):
        pcdcodec.open(path)
    assert_cli_refuses(path, tmp_path, capsys)


def test_removed_first_keyframe_marker_in_a_file_without_seal(clean: Path, tmp_path: Path) -> None:
    """Files written before seals: a closed file with depth but no readable frame is refused."""
    path = tmp_path / "nokey-old.pcdc"
    rewrite(clean, path, drop_first_keyframe_marker, strip_integrity=True)
    with pytest.raises(pcdcodec.DecodeError, match=r"5 depth message\(s\), but no frame"):
        pcdcodec.open(path)


def test_removed_last_color_packet_is_refused(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = hostile(clean, tmp_path / "nolast.pcdc", drop_last_color_packet)
    with pytest.raises(pcdcodec.DecodeError, match=r"nolast\.pcdc.*/camera/color\":4"):
        pcdcodec.open(path)
    assert_cli_refuses(path, tmp_path, capsys)


def test_removed_last_color_packet_recovers_the_other_frames(
    clean: Path, tmp_path: Path, decoded: dict[int, tuple[Any, Any]]
) -> None:
    path = hostile(clean, tmp_path / "nolast.pcdc", drop_last_color_packet)
    got = pcdcodec.recover(path, tmp_path / "back.pcdc")
    assert got == 5  # the last frame keeps its depth; its color alone is lost
    assert got.color_missing == 1
    assert [(loss.stream, loss.frames) for loss in got.lost] == [("color", (4,))]
    with pcdcodec.open(tmp_path / "back.pcdc") as rec:
        assert rec.verify().ok
        assert rec.color_missing == [4]
        for f in rec:
            color = None if f.index == 4 else decoded[f.timestamp_ns][0]
            np.testing.assert_array_equal(f.color, color)
            np.testing.assert_array_equal(f.depth, decoded[f.timestamp_ns][1])


def test_removed_last_color_packet_in_a_file_without_seal_fails_verify(
    clean: Path, tmp_path: Path
) -> None:
    path = tmp_path / "nolast-old.pcdc"
    rewrite(clean, path, drop_last_color_packet, strip_integrity=True)
    with pcdcodec.open(path) as rec:
        assert len(rec) == 4  # read as before
        report = rec.verify()
    assert any("no color packet" in e for e in report.errors)


def test_unchunked_file_is_refused(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = hostile(clean, tmp_path / "flat.pcdc", lambda ms: ms, chunked=False)
    with pytest.raises(pcdcodec.DecodeError, match=r"flat\.pcdc.*outside chunks"):
        pcdcodec.open(path)
    assert_cli_refuses(path, tmp_path, capsys)
    with pytest.raises(pcdcodec.DecodeError, match=r"flat\.pcdc.*outside chunks"):
        pcdcodec.recover(path, tmp_path / "back.pcdc")
    # The same for a file written before seals.
    old = tmp_path / "flat-old.pcdc"
    rewrite(clean, old, chunked=False, strip_integrity=True)
    with pytest.raises(pcdcodec.DecodeError, match="outside chunks"):
        pcdcodec.open(old)


def test_swapped_color_packets_are_refused(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = hostile(clean, tmp_path / "swap.pcdc", swap_color_packets)
    with pytest.raises(pcdcodec.DecodeError, match=r"swap\.pcdc.*not in the sealed order"):
        pcdcodec.open(path)
    assert_cli_refuses(path, tmp_path, capsys)


def test_swapped_color_payloads_fail_the_frames_they_reach(
    clean: Path, tmp_path: Path, decoded: dict[int, tuple[Any, Any]]
) -> None:
    """The messages keep their times and order (the seal holds); their data trade places."""

    def swap_data(ms: list[Message]) -> list[Message]:
        a, b = positions(ms, fmt.TOPIC_COLOR)[1:3]
        ms[a], ms[b] = with_data(ms[a], ms[b].data), with_data(ms[b], ms[a].data)
        return ms

    path = hostile(clean, tmp_path / "swapdata.pcdc", swap_data)
    with pcdcodec.open(path) as rec:
        np.testing.assert_array_equal(rec[0].color, decoded[rec.timestamps[0]][0])
        for i in range(1, 5):
            with pytest.raises(pcdcodec.DecodeError, match=rf"swapdata\.pcdc.*frame {i} "):
                rec[i]
        report = rec.verify()
    assert sum("do not match the frame digest" in e for e in report.errors) >= 2


def test_swapped_depth_payloads_fail_the_frames(clean: Path, tmp_path: Path) -> None:
    """Each depth message checks its own image, but not which frame it belongs to: the frame's
    digest message does."""

    def swap_depth(ms: list[Message]) -> list[Message]:
        a, b = positions(ms, fmt.TOPIC_DEPTH)[1:3]
        ms[a], ms[b] = with_data(ms[a], ms[b].data), with_data(ms[b], ms[a].data)
        return ms

    path = hostile(clean, tmp_path / "swapdepth.pcdc", swap_depth)
    with pcdcodec.open(path) as rec:
        rec.depth(0)
        for i in (1, 2):
            with pytest.raises(pcdcodec.DecodeError, match=rf"frame {i} .*frame's digest"):
                rec.depth(i)
        assert sum("frame's digest" in e for e in rec.verify().errors) == 2


def test_swapped_poses_fail_the_frames(tmp_path: Path) -> None:
    path = tmp_path / "poses.pcdc"
    with pcdcodec.open(path, "w", intrinsics=CAMERA, color="ffv1", depth="zstd") as w:
        for k, (c, d, ts) in enumerate(frames(4)):
            pose = np.eye(4)
            pose[0, 3] = k
            w.write(c, d, ts, pose=pose)

    def swap_pose(ms: list[Message]) -> list[Message]:
        for topic in (fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX):
            a, b = positions(ms, topic)[0:2]
            ms[a], ms[b] = with_data(ms[a], ms[b].data), with_data(ms[b], ms[a].data)
        return ms

    bad = hostile(path, tmp_path / "swappose.pcdc", swap_pose)
    with pcdcodec.open(bad) as rec:
        assert rec[2].pose[0, 3] == 2
        for i in (0, 1):
            with pytest.raises(pcdcodec.DecodeError, match=rf"frame {i} .*pose does not match"):
                rec[i]
        assert not rec.verify().ok


def _pose_only(path: Path, dst: Path, k: int, data: bytes) -> Path:
    """``path`` as written before digests and pose matrices, the pose of frame ``k`` replaced."""
    contents = without_integrity(read(path))
    contents.channels.pop(fmt.TOPIC_POSE_MATRIX, None)
    ms = [m for m in contents.messages if m.topic != fmt.TOPIC_POSE_MATRIX]
    at = positions(ms, fmt.TOPIC_POSE)[k]
    ms[at] = with_data(ms[at], data)
    contents.messages = ms
    write(contents, dst)
    return dst


def test_damaged_poses_without_digests_give_a_decode_error_naming_the_file(
    tmp_path: Path,
) -> None:
    from pcdcodec.recording import _header as header

    path = tmp_path / "poses.pcdc"
    with pcdcodec.open(path, "w", intrinsics=CAMERA, color="ffv1", depth="zstd") as w:
        for k, (c, d, ts) in enumerate(frames(3)):
            pose = np.eye(4)
            pose[0, 3] = k
            w.write(c, d, ts, pose=pose)

    def transform(translation: Any, rotation: Any) -> bytes:
        return header.FrameTransform(0, "world", "camera", translation, rotation).encode()

    damaged = {
        "zero": transform((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 0.0)),
        "nan": transform((np.nan, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0)),
        "huge": transform((1.0, 2.0, 3.0), (1e200, 0.0, 0.0, 1.0)),
        "short": transform((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0))[:-1],
    }
    for name, data in damaged.items():
        bad = _pose_only(path, tmp_path / f"{name}.pcdc", 1, data)
        with pcdcodec.open(bad) as rec:
            assert rec[2].pose[0, 3] == 2
            with pytest.raises(pcdcodec.DecodeError, match=rf"{name}\.pcdc.*frame 1 .*pose"):
                rec[1]
    # Unchanged messages still give their poses.
    plain = _pose_only(path, tmp_path / "plain.pcdc", 1, transform((1.0, 0.0, 0.0), (0, 0, 0, 1)))
    with pcdcodec.open(plain) as rec:
        assert [p[0, 3] for p in rec.poses()] == [0, 1, 2]


def test_changed_color_byte_gives_an_error_not_wrong_color(
    clean: Path, tmp_path: Path, decoded: dict[int, tuple[Any, Any]]
) -> None:
    path = hostile(clean, tmp_path / "byte.pcdc", change_color_byte)
    with pcdcodec.open(path) as rec:
        # The frames before the changed packet are right; none after it is returned.
        for i in range(2):
            np.testing.assert_array_equal(rec[i].color, decoded[rec.timestamps[i]][0])
        for i in range(2, 5):
            with pytest.raises(pcdcodec.DecodeError, match=rf"byte\.pcdc.*frame {i} "):
                rec[i]
        with pytest.raises(pcdcodec.DecodeError, match="color packet 2"):
            rec.packet(2)
        report = rec.verify()
    assert not report.ok
    assert any("do not match the frame digest" in e for e in report.errors)


def test_closed_file_without_its_seal_is_refused(clean: Path, tmp_path: Path) -> None:
    contents = read(clean)
    contents.metadata = [(n, d) for n, d in contents.metadata if n != fmt.SEAL_NAME]
    path = tmp_path / "unsealed.pcdc"
    write(contents, path)
    with pytest.raises(pcdcodec.DecodeError, match=r"unsealed\.pcdc.*seal record .* missing"):
        pcdcodec.open(path)


def test_depth_only_file_with_a_frame_removed_is_refused(tmp_path: Path) -> None:
    path = record(tmp_path / "depth.pcdc", frames(), color=None)
    with pcdcodec.open(path) as rec:
        assert rec.verify().ok

    def drop(ms: list[Message]) -> list[Message]:
        k = positions(ms, fmt.TOPIC_DEPTH)[2]
        return ms[:k] + ms[k + 1 :]

    bad = hostile(path, tmp_path / "depth-gap.pcdc", drop)
    with pytest.raises(pcdcodec.DecodeError, match="frames: sealed '5', found '4'"):
        pcdcodec.open(bad)


def test_packets_held_back_by_the_encoder_are_sealed(tmp_path: Path) -> None:
    """With a lookahead the encoder's last packets come at close, after the last frame's
    digest: the seal covers them."""
    items = frames(12)
    path = record(tmp_path / "ahead.pcdc", items, color={"id": "h264", "low_delay": False})
    with pcdcodec.open(path) as rec:
        tail = int(rec.index.metadata[fmt.SEAL_NAME]["tail_packets"])
        assert tail > 0
        assert len(rec) == 12
        assert rec.verify().ok
        last = rec[11].color

    def change_last(ms: list[Message]) -> list[Message]:
        k = positions(ms, fmt.TOPIC_COLOR)[-1]
        data = bytearray(ms[k].data)
        data[-3] ^= 0x01
        ms[k] = with_data(ms[k], bytes(data))
        return ms

    bad = hostile(path, tmp_path / "ahead-bad.pcdc", change_last)
    with pcdcodec.open(bad) as rec:
        report = rec.verify()
        assert any("the seal's digest of the last" in e for e in report.errors)
        with pytest.raises(pcdcodec.DecodeError, match="the seal's digest"):
            np.testing.assert_array_equal(rec[11].color, last)


def test_join_checks_each_part_and_seals_the_result(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    codec = {"id": "h264", "low_delay": False}  # each part ends with packets held back
    a = record(tmp_path / "a.pcdc", frames(6), color=codec)
    b = record(tmp_path / "b.pcdc", frames(6, offset=6), color=codec)
    expected = {}
    for part in (a, b):
        with pcdcodec.open(part) as rec:
            assert int(rec.index.metadata[fmt.SEAL_NAME]["tail_packets"]) > 0
            expected.update({f.timestamp_ns: f.color for f in rec})
    assert join([a, b], tmp_path / "ab.pcdc") == 12
    with pcdcodec.open(tmp_path / "ab.pcdc") as rec:
        assert rec.index.metadata[fmt.SEAL_NAME]["frames"] == "12"
        assert rec.verify().ok
        for f in rec:
            np.testing.assert_array_equal(f.color, expected[f.timestamp_ns])
    bad = hostile(b, tmp_path / "b-bad.pcdc", change_color_byte)
    with pytest.raises(pcdcodec.DecodeError, match=r"b-bad\.pcdc.*do not match their digest"):
        join([a, bad], tmp_path / "ab2.pcdc")
    assert not (tmp_path / "ab2.pcdc").exists()


def _swap_depths(ms: list[Message]) -> list[Message]:
    a, b = positions(ms, fmt.TOPIC_DEPTH)[1:3]
    ms[a], ms[b] = with_data(ms[a], ms[b].data), with_data(ms[b], ms[a].data)
    return ms


def _flip_depth_byte(ms: list[Message]) -> list[Message]:
    k = positions(ms, fmt.TOPIC_DEPTH)[2]
    data = bytearray(ms[k].data)
    data[len(data) // 2] ^= 0x10
    ms[k] = with_data(ms[k], bytes(data))
    return ms


def _change_pose(ms: list[Message]) -> list[Message]:
    k = positions(ms, fmt.TOPIC_POSE_MATRIX)[3]
    values = np.frombuffer(ms[k].data, np.float64).copy()
    values[3] += 0.5
    ms[k] = with_data(ms[k], values.tobytes())
    return ms


@pytest.mark.parametrize(
    ("edit", "what"),
    [
        (_swap_depths, "frame at t=1033333333 ns.*depth message does not match"),
        (_flip_depth_byte, "frame at t=1066666666 ns.*depth message does not match"),
        (_change_pose, "frame at t=1100000000 ns.*pose messages do not match"),
    ],
)
def test_join_refuses_a_part_whose_depth_or_pose_fails_its_digest(
    tmp_path: Path, edit: Any, what: str
) -> None:
    a = record(tmp_path / "a.pcdc", frames(6))
    b = tmp_path / "b.pcdc"
    with pcdcodec.open(
        b, "w", intrinsics=CAMERA, depth_scale=1000.0, color="ffv1", depth="zstd"
    ) as w:
        for k, (c, d, ts) in enumerate(frames(6, offset=6)):
            w.write(c, d, ts, pose=np.eye(4) + np.eye(4, k=3) * k)
    later = [(c, d, ts + 400_000_000) for c, d, ts in frames(6)]
    c_part = record(tmp_path / "c.pcdc", later)
    bad = hostile(a, tmp_path / "a-bad.pcdc", edit) if edit is not _change_pose else None
    if bad is None:
        bad = hostile(b, tmp_path / "b-bad.pcdc", edit)
        parts = [a, bad, c_part]
        what = what.replace("1100000000", "1299999997")
    else:
        parts = [bad, b, c_part]
    with pcdcodec.open(bad) as rec:  # the part itself reads wrong, and verify says so
        assert not rec.verify().ok
    name = re.escape(str(bad))
    with pytest.raises(pcdcodec.DecodeError, match=f"'{name}': {what}"):
        join(parts, tmp_path / "joined.pcdc")
    assert not (tmp_path / "joined.pcdc").exists()
    assert not [p for p in tmp_path.iterdir() if "joined" in p.name]  # nothing left behind
    assert join([a, b, c_part], tmp_path / "good.pcdc") == 18


def test_a_killed_writer_leaves_the_frames_whose_digest_was_written(tmp_path: Path) -> None:
    path = tmp_path / "killed.pcdc"
    w = pcdcodec.open(path, "w", intrinsics=CAMERA, depth_scale=1000.0, color="ffv1", in_flight=1)
    items = frames(6)
    for c, d, ts in items:
        w.write(c, d, ts)
    w.abort()
    # The writing thread is done once abort() returns: the count is final, and how many frames
    # it reached before the abort depends only on timing.
    complete = w.frames_complete
    with pcdcodec.open(path) as rec:
        assert not rec.indexed
        assert len(rec) == complete
        assert 1 <= complete <= 6
        for f, (c, _, ts) in zip(rec, items, strict=False):
            assert f.timestamp_ns == ts
            np.testing.assert_array_equal(f.color, c)
    assert pcdcodec.recover(path, tmp_path / "back.pcdc") == complete
    with pcdcodec.open(tmp_path / "back.pcdc") as rec:
        assert rec.verify().ok
