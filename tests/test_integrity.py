"""Trust what comes back: a damaged recording gives the right frames or a DecodeError, never
wrong data, and never an exception from outside pcdcodec's tree."""

from __future__ import annotations

import shutil
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.cli import main
from pcdcodec.datasets import load_sample
from pcdcodec.recording import _index as fmt
from pcdcodec.recording.rewrite import rewrite

from .golden.make_recording_golden import GOLDEN, golden_frames

W, H = 160, 120
CAMERA = pcdcodec.CameraIntrinsics(W, H, 525.0, 525.0, 79.5, 59.5)


def small_frames(n: int = 10) -> list[tuple[Any, Any, int]]:
    """``n`` frames of the bundled sample, a quarter of its size each way."""
    sample = load_sample(max_frames=n)
    return [
        (
            np.ascontiguousarray(f.color[::4, ::4]),
            np.ascontiguousarray(f.depth[::4, ::4]),
            f.timestamp_ns,
        )
        for f in sample
    ]


def write(path: Path, frames: list[tuple[Any, Any, int]], **options: Any) -> Path:
    options.setdefault("intrinsics", CAMERA)
    options.setdefault("depth_scale", 5000.0)
    with pcdcodec.open(path, "w", **options) as rec:
        for color, depth, ts in frames:
            rec.write(color if options.get("color", "h264") else None, depth, ts)
    return path


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 10-frame h264 + jpegxl recording with user metadata."""
    path = tmp_path_factory.mktemp("integrity") / "clean.pcdc"
    return write(path, small_frames(), depth="jpegxl", metadata={"site": "lab"})


@pytest.fixture(scope="module")
def decoded(clean: Path) -> list[tuple[int, Any, Any]]:
    with pcdcodec.open(clean) as rec:
        return [(f.timestamp_ns, f.color, f.depth) for f in rec]


def summary_records(data: bytes) -> list[tuple[int, int, int]]:
    """(record offset, opcode, content length) of every record in the summary section."""
    start = struct.unpack_from("<Q", data, len(data) - 8 - 20 - 9 + 9)[0]
    end = len(data) - 8 - 29
    out = []
    pos = start
    while pos < end:
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        out.append((pos, opcode, length))
        pos += 9 + length
    return out


def fix_summary_crc(data: bytearray) -> None:
    """Recompute the footer's summary CRC, as a writer of a wrong but consistent index would."""
    footer = len(data) - 8 - 29
    start = struct.unpack_from("<Q", data, footer + 9)[0]
    crc = zlib.crc32(bytes(data[footer : footer + 25]), zlib.crc32(bytes(data[start:footer])))
    struct.pack_into("<I", data, footer + 25, crc)


def channel_ids(path: Path) -> dict[str, int]:
    with pcdcodec.open(path) as rec:
        return {c.topic: c.id for c in rec.index.channels.values()}


def read_all(path: Path) -> tuple[list[tuple[int, Any, Any]], pcdcodec.recording.VerifyReport]:
    with pcdcodec.open(path) as rec:
        frames = [(f.timestamp_ns, f.color, f.depth) for f in rec]
        return frames, rec.verify()


def assert_same(frames: list[tuple[int, Any, Any]], expected: list[tuple[int, Any, Any]]) -> None:
    assert len(frames) == len(expected)
    for (t, c, d), (te, ce, de) in zip(frames, expected, strict=True):
        assert t == te
        np.testing.assert_array_equal(c, ce)
        np.testing.assert_array_equal(d, de)


# -- 1. a damaged index ---------------------------------------------------------------------------


def test_channel_id_overwritten_in_a_chunk_index(
    tmp_path: Path, clean: Path, decoded: list[Any]
) -> None:
    data = bytearray(clean.read_bytes())
    ids = channel_ids(clean)
    color, depth = ids[fmt.TOPIC_COLOR], ids[fmt.TOPIC_DEPTH]
    changed = 0
    for pos, opcode, _ in summary_records(bytes(data)):
        # Content: start, end, chunk offset, chunk length (4 x u64), then the map's byte
        # length (u32) and its first channel id (u16).
        at = pos + 9 + 32 + 4
        if opcode == 0x08 and struct.unpack_from("<H", data, at)[0] == color and changed < 3:
            struct.pack_into("<H", data, at, depth)
            changed += 1
    assert changed == 3
    path = tmp_path / "ci.pcdc"
    path.write_bytes(bytes(data))
    frames, report = read_all(path)
    assert_same(frames, decoded)  # found by a scan, since the summary fails its CRC
    assert not report.ok
    assert "summary" in report.errors[0]
    assert "CRC" in report.errors[0]


def test_consistent_but_wrong_index_is_not_trusted(
    tmp_path: Path, clean: Path, decoded: list[Any]
) -> None:
    """The same damage with the summary CRC made to match: the statistics disagree."""
    data = bytearray(clean.read_bytes())
    ids = channel_ids(clean)
    for pos, opcode, _ in summary_records(bytes(data)):
        at = pos + 9 + 32 + 4
        if opcode == 0x08 and struct.unpack_from("<H", data, at)[0] == ids[fmt.TOPIC_COLOR]:
            struct.pack_into("<H", data, at, ids[fmt.TOPIC_DEPTH])
            break
    fix_summary_crc(data)
    path = tmp_path / "ci2.pcdc"
    path.write_bytes(bytes(data))
    frames, report = read_all(path)
    assert_same(frames, decoded)
    assert any("statistics" in e for e in report.errors)


def test_chunk_offset_out_of_the_file(tmp_path: Path, clean: Path, decoded: list[Any]) -> None:
    data = bytearray(clean.read_bytes())
    pos = next(p for p, op, _ in summary_records(bytes(data)) if op == 0x08)
    struct.pack_into("<Q", data, pos + 9 + 16, 2**63 + 12345)  # chunk_start_offset
    fix_summary_crc(data)
    path = tmp_path / "far.pcdc"
    path.write_bytes(bytes(data))
    frames, report = read_all(path)
    assert_same(frames, decoded)
    assert any("outside the data section" in e for e in report.errors)


def test_wrong_time_in_a_consistent_index_gives_an_error_not_a_frame(
    tmp_path: Path, clean: Path, decoded: list[Any]
) -> None:
    data = bytearray(clean.read_bytes())
    ids = channel_ids(clean)
    depth_indexes = [
        p
        for p, op, _ in summary_records(bytes(data))
        if op == 0x08 and struct.unpack_from("<H", data, p + 9 + 36)[0] == ids[fmt.TOPIC_DEPTH]
    ]
    pos = depth_indexes[4]
    t = struct.unpack_from("<Q", data, pos + 9)[0]
    struct.pack_into("<QQ", data, pos + 9, t + 1, t + 1)  # frame 4's time, off by 1 ns
    fix_summary_crc(data)
    path = tmp_path / "time.pcdc"
    path.write_bytes(bytes(data))
    # The summary disagrees with the seal, so the frames are found by reading the file.
    frames, report = read_all(path)
    assert_same(frames, decoded)
    assert not report.ok
    assert any("disagrees with the file's seal" in e for e in report.errors)
    # A file without a seal (written before seals) has only the summary to go by.
    old = tmp_path / "old.pcdc"
    rewrite(clean, old, strip_integrity=True)
    data = bytearray(old.read_bytes())
    ids = channel_ids(old)
    depth_indexes = [
        p
        for p, op, _ in summary_records(bytes(data))
        if op == 0x08 and struct.unpack_from("<H", data, p + 9 + 36)[0] == ids[fmt.TOPIC_DEPTH]
    ]
    pos = depth_indexes[4]
    t = struct.unpack_from("<Q", data, pos + 9)[0]
    struct.pack_into("<QQ", data, pos + 9, t + 1, t + 1)
    fix_summary_crc(data)
    path.write_bytes(bytes(data))
    with pcdcodec.open(path) as rec:
        assert len(rec) == len(decoded)
        with pytest.raises(pcdcodec.DecodeError, match=r"frame 4 .*no decodable color packet"):
            rec[4]
        np.testing.assert_array_equal(rec[5].depth, decoded[5][2])
        report = rec.verify()
    assert any("'/camera/depth'" in e for e in report.errors)


def test_zeroed_channel_record_in_the_summary(
    tmp_path: Path, clean: Path, decoded: list[Any]
) -> None:
    data = bytearray(clean.read_bytes())
    for pos, opcode, length in summary_records(bytes(data)):
        if opcode == 0x04:
            data[pos + 9 : pos + 9 + length] = bytes(length)
    path = tmp_path / "ch.pcdc"
    path.write_bytes(bytes(data))
    frames, report = read_all(path)
    assert_same(frames, decoded)
    assert not report.ok


def test_damaged_chunk_with_a_damaged_summary_is_an_error(
    tmp_path: Path, clean: Path, decoded: list[Any]
) -> None:
    data = bytearray(clean.read_bytes())
    with pcdcodec.open(clean) as rec:
        offset = int(rec._offsets[5])
    data[offset + 100] ^= 0x10
    data[-8 - 29 + 9] ^= 0x01  # summary start, in the footer
    path = tmp_path / "both.pcdc"
    path.write_bytes(bytes(data))
    with pytest.raises(pcdcodec.DecodeError, match=f"damaged at byte offset {offset}.*recover"):
        pcdcodec.open(path)
    recovered = tmp_path / "r.pcdc"
    # Every frame but the one whose depth chunk is damaged, each as written.
    count = pcdcodec.recover(path, recovered)
    assert count == 9
    assert [(loss.stream, loss.frames) for loss in count.lost] == [("frame", (5,))]
    assert "depth message is lost" in count.lost[0].reason
    frames, report = read_all(recovered)
    assert report.ok
    assert_same(frames, decoded[:5] + decoded[6:])


def test_verify_counts_frames_from_the_file_not_the_index(
    tmp_path: Path, clean: Path, decoded: list[Any]
) -> None:
    """A chunk index dropped from a consistent summary: verify finds the missing frame."""
    data = bytearray(clean.read_bytes())
    ids = channel_ids(clean)
    records = summary_records(bytes(data))
    pos, _, length = next(
        r
        for r in records
        if r[1] == 0x08 and struct.unpack_from("<H", data, r[0] + 45)[0] == ids[fmt.TOPIC_DEPTH]
    )
    # Turn the chunk index into a record type the summary ignores, and fix the statistics.
    data[pos] = 0x0E
    struct.pack_into("<Q", data, pos + 1, length)
    stats = next(r for r in records if r[1] == 0x0B)[0] + 9
    (count,) = struct.unpack_from("<Q", data, stats)
    struct.pack_into("<Q", data, stats, count - 1)
    fix_summary_crc(data)
    path = tmp_path / "drop.pcdc"
    path.write_bytes(bytes(data))
    _, report = read_all(path)
    assert not report.ok


# -- 2. the file's own settings ---------------------------------------------------------------


def _edit_metadata(src: Path, dst: Path, old: bytes, new: bytes, record: str) -> None:
    data = bytearray(src.read_bytes())
    with pcdcodec.open(src) as rec:
        start = rec.index.metadata_offsets[record]
    at = data.index(old, start)
    data[at : at + len(old)] = new
    dst.write_bytes(bytes(data))


@pytest.mark.parametrize(
    ("old", "new", "record"),
    [
        (b"5000.0", b"9000.0", "pcdcodec"),  # depth scale
        (b'"fx": 525.0', b'"fx": 925.0', "pcdcodec"),
        (b'"effort": 2', b'"effort": 9', "pcdcodec"),  # depth codec config
        (b"lab", b"lob", "user"),
    ],
    ids=["depth_scale", "fx", "codec", "user"],
)
def test_changed_settings_are_refused(
    tmp_path: Path, clean: Path, old: bytes, new: bytes, record: str
) -> None:
    path = tmp_path / "m.pcdc"
    _edit_metadata(clean, path, old, new, record)
    with pytest.raises(pcdcodec.DecodeError, match=f"{record}.*does not match its digest"):
        pcdcodec.open(path)
    assert main(["verify", str(path)]) == 1


def test_settings_of_old_files_are_cross_checked(tmp_path: Path) -> None:
    """Format version 1 files carry no digest; the CRC-checked channels and calibration do."""
    path = tmp_path / "old.pcdc"
    _edit_metadata(GOLDEN, path, b"5000.0", b"9000.0", "pcdcodec")
    with pytest.raises(pcdcodec.DecodeError, match=r"depth_scale is 5000\.0"):
        pcdcodec.open(path)
    _edit_metadata(GOLDEN, path, b'"fx": 52.5', b'"fx": 92.5', "pcdcodec")
    with pytest.raises(pcdcodec.DecodeError, match=r"calibration message .* disagrees"):
        pcdcodec.open(path)


def test_old_files_without_digest_still_read() -> None:
    with pcdcodec.open(GOLDEN) as rec:
        assert rec.format_version == 1
        assert fmt.DIGEST_KEY not in rec.index.metadata[fmt.METADATA_NAME]
        assert rec.metadata == {"site": "lab"}
        assert rec.depth_scale == 5000.0
        for frame, (color, depth, ts) in zip(rec, golden_frames(), strict=True):
            assert frame.timestamp_ns == ts
            np.testing.assert_array_equal(frame.color, color)
            np.testing.assert_array_equal(frame.depth, depth)
        assert rec.verify().ok


def test_every_metadata_record_is_sealed(clean: Path) -> None:
    with pcdcodec.open(clean) as rec:
        assert set(rec.index.metadata) == {"pcdcodec", "user", fmt.SEAL_NAME}
        for name, data in rec.index.metadata.items():
            assert data[fmt.DIGEST_KEY] == fmt.digest(name, data)
        assert rec.metadata == {"site": "lab"}
        assert rec.index.metadata["pcdcodec"][fmt.RECORDS_KEY] == '["user"]'


def test_digest_key_is_reserved(tmp_path: Path) -> None:
    with pytest.raises(pcdcodec.InputError, match="reserved"):
        pcdcodec.open(tmp_path / "x.pcdc", "w", intrinsics=CAMERA, metadata={fmt.DIGEST_KEY: 1})
    assert not (tmp_path / "x.pcdc").exists()


def test_removed_user_record_is_noticed(tmp_path: Path, clean: Path) -> None:
    data = bytearray(clean.read_bytes())
    with pcdcodec.open(clean) as rec:
        offset = rec.index.metadata_offsets["user"]
    data[offset] = 0x10  # no longer a metadata record: a scan passes over it... or stops
    data[-8 - 29 + 9] ^= 0x01  # and the summary is unusable
    path = tmp_path / "nouser.pcdc"
    path.write_bytes(bytes(data))
    with pytest.raises(pcdcodec.DecodeError):
        pcdcodec.open(path)


def test_changes_outside_chunks_fail_the_data_crc(tmp_path: Path, clean: Path) -> None:
    data = bytearray(clean.read_bytes())
    at = data.index(b"pcdcodec ", 8)  # the header's library string
    data[at + 9] ^= 0x01
    path = tmp_path / "lib.pcdc"
    path.write_bytes(bytes(data))
    with pcdcodec.open(path) as rec:
        report = rec.verify()
    assert any("data section fails its CRC" in e for e in report.errors)


# -- 3 and 4. errors of the project's own, shapes bounded by the camera -------------------------


def test_depth_frame_larger_than_the_camera(tmp_path: Path) -> None:
    cam = pcdcodec.CameraIntrinsics(64, 48, 50.0, 50.0, 31.5, 23.5)
    path = tmp_path / "big.pcdc"
    with pcdcodec.open(path, "w", intrinsics=cam, color=None, depth="zstd") as rec:
        rec.write(None, np.full((48, 64), 1000, np.uint16), 0)
        rec._shape = (480, 640)  # a writer that does not check, or a crafted file
        rec.write(None, np.zeros((480, 640), np.uint16), 1)
    with pcdcodec.open(path) as rec:
        assert rec[0].depth.shape == (48, 64)
        with pytest.raises(pcdcodec.DecodeError, match=r"frame 1 .*640x480.*camera is 64x48"):
            rec[1]
        report = rec.verify()
    assert not report.ok
    assert "640x480" in report.errors[0]


def test_metadata_that_does_not_parse(tmp_path: Path, clean: Path) -> None:
    """Bytes that are not UTF-8 inside a metadata record, with an unusable summary."""
    data = bytearray(clean.read_bytes())
    with pcdcodec.open(clean) as rec:
        offset = rec.index.metadata_offsets["pcdcodec"]
    at = data.index(b"intrinsics", offset)
    data[at] = 0xFF
    data[-8 - 29 + 9] ^= 0x01
    path = tmp_path / "utf.pcdc"
    path.write_bytes(bytes(data))
    with pytest.raises(pcdcodec.DecodeError, match=f"byte offset {offset}"):
        pcdcodec.open(path)


def test_cli_prints_an_error_not_a_traceback(
    tmp_path: Path, clean: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = bytearray(clean.read_bytes())
    data[-8 - 29 + 9] ^= 0x40
    with pcdcodec.open(clean) as rec:
        offset = rec.index.metadata_offsets["pcdcodec"]
    data[data.index(b"intrinsics", offset)] = 0xFF
    path = tmp_path / "x.pcdc"
    path.write_bytes(bytes(data))
    for command in ("info", "verify"):
        assert main([command, str(path)]) == 1
        err = capsys.readouterr().err
        assert err.startswith("error: ")
        assert str(path) in err
        assert "Traceback" not in err


# -- 9. recover ---------------------------------------------------------------------------------


def test_recover_is_exported_and_names_the_given_paths(tmp_path: Path, clean: Path) -> None:
    assert pcdcodec.recover is pcdcodec.recording.recover
    assert "recover" in pcdcodec.__all__
    path = tmp_path / "bad.pcdc"
    _edit_metadata(clean, path, b"lab", b"lob", "user")
    out = tmp_path / "out.pcdc"
    with pytest.raises(pcdcodec.DecodeError) as info:
        pcdcodec.recover(path, out)
    assert str(path) in str(info.value)
    assert "partial" not in str(info.value)
    assert not out.exists()
    assert list(tmp_path.glob(".out.pcdc*")) == []


def test_recover_of_a_clean_file_keeps_its_settings(tmp_path: Path, clean: Path) -> None:
    out = tmp_path / "copy.pcdc"
    assert pcdcodec.recover(clean, out) == 10
    with pcdcodec.open(out) as rec:
        assert rec.metadata == {"site": "lab"}
        assert rec.verify().ok
    shutil.copy(GOLDEN, tmp_path / "old.pcdc")
    assert pcdcodec.recover(tmp_path / "old.pcdc", tmp_path / "old2.pcdc") == 4
