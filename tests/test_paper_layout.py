"""The paper's two-file layout: a recording out to a video, LZ4 depth and frames.json, and back."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.color import PyAVCodec
from pcdcodec.convert.paper import export_paper, import_paper
from pcdcodec.errors import DecodeError, InputError

av = pytest.importorskip("av")
lz4_frame = pytest.importorskip("lz4.frame")

FRAMES = 8
#: The two codecs the layout is checked with in depth: the default (lossy) and a lossless one.
CODECS = ["h264", "ffv1"]


def _available(name: str) -> bool:
    cls = pcdcodec.codec_class(name)
    return issubclass(cls, PyAVCodec) and cls.is_available()


#: Every other PyAV bitstream, and H.264 with B-frames (decode order differs from display order).
OTHER_CODECS: list[Any] = [
    name
    for name in ("h265", "av1", "vp9", "mjpeg", "mpeg4", "huffyuv", "ffvhuff", "h264-lossless")
    if _available(name)
] + [{"id": "h264", "bframes": 2}]


def _codec_id(spec: Any) -> str:
    return spec if isinstance(spec, str) else "-".join(f"{v}" for v in spec.values())


def _record(path: Path, color: Any, depth: Any = "jpegxl") -> Path:
    seq = pcdcodec.load_sample(max_frames=FRAMES)
    with pcdcodec.open(
        path,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        color=color,
        depth=depth,
    ) as rec:
        if color is None:  # depth only: the sample's color is left out on purpose
            rec.write_frames((None, f.depth, f.timestamp_ns) for f in seq)
        else:
            rec.write_frames(seq)
    return path


def _frames(path: Path) -> list[pcdcodec.Frame]:
    with pcdcodec.open(path) as rec:
        return list(rec)


def _packets(path: Path) -> list[bytes]:
    with pcdcodec.open(path) as rec:
        return [p.data for p in rec.packets()]


@pytest.fixture(scope="module", params=CODECS)
def exported(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Any:
    """(recording, layout folder, export summary) for each codec in CODECS."""
    base = tmp_path_factory.mktemp(f"paper-{request.param}")
    recording = _record(base / "a.pcdc", request.param)
    calls: list[int] = []
    summary = export_paper(recording, base / "layout", progress=calls.append)
    assert calls == list(range(1, FRAMES + 1))
    return recording, base / "layout", summary


@pytest.fixture(scope="module")
def imported(exported: Any) -> tuple[Path, Path]:
    recording, layout, _ = exported
    out = layout.parent / "b.pcdc"
    calls: list[int] = []
    assert import_paper(layout, out, progress=calls.append) == FRAMES
    assert calls == list(range(1, FRAMES + 1))
    return recording, out


def _doc(layout: Path) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((layout / "frames.json").read_text())
    return doc


def _decode_video(path: Path) -> list[Any]:
    with av.open(str(path)) as container:
        return list(container.decode(video=0))


# -- export --------------------------------------------------------------------------------------


def test_export_writes_the_three_files(exported: Any) -> None:
    _, layout, summary = exported
    assert summary["frames"] == FRAMES
    assert summary["video_file"] == "color.mkv"
    assert sorted(p.name for p in layout.iterdir()) == ["color.mkv", "depth.lz4", "frames.json"]
    for name, size in summary["bytes"].items():
        assert (layout / name).stat().st_size == size > 0


def test_video_plays_every_frame_exactly_as_recorded(exported: Any) -> None:
    recording, layout, _ = exported
    frames = _decode_video(layout / "color.mkv")
    original = _frames(recording)
    assert len(frames) == len(original) == FRAMES
    # Same bitstream, same decoder: the video shows exactly the recording's colors. For FFV1
    # that is also the camera's RGB, bit for bit.
    for frame, rec_frame in zip(frames, original, strict=True):
        assert np.array_equal(frame.to_ndarray(format="rgb24"), rec_frame.color)
    if layout.parent.name.startswith("paper-ffv1"):
        seq = pcdcodec.load_sample(max_frames=FRAMES)
        for frame, src in zip(frames, seq, strict=True):
            assert np.array_equal(frame.to_ndarray(format="rgb24"), src.color)
    assert [f.pts for f in frames] == [e["pts"] for e in _doc(layout)["frames"]]


def test_depth_lz4_frames_decompress_to_the_recorded_depth(exported: Any) -> None:
    recording, layout, _ = exported
    data = (layout / "depth.lz4").read_bytes()
    entries = _doc(layout)["frames"]
    original = _frames(recording)
    end = 0
    for entry, frame in zip(entries, original, strict=True):
        assert entry["depth_offset"] == end  # back to back, nothing in between
        end += entry["depth_length"]
        blob = data[entry["depth_offset"] : end]
        raw = lz4_frame.decompress(blob)
        assert raw == frame.depth.astype("<u2").tobytes()
        assert lz4_frame.get_frame_info(blob)["content_size"] == len(raw)
    assert end == len(data)


@pytest.mark.skipif(shutil.which("lz4") is None, reason="the lz4 command-line tool is absent")
def test_lz4_cli_decompresses_the_whole_depth_file(exported: Any) -> None:
    recording, layout, _ = exported
    result = subprocess.run(
        ["lz4", "-d", "-c", str(layout / "depth.lz4")], capture_output=True, check=True
    )
    expected = b"".join(f.depth.astype("<u2").tobytes() for f in _frames(recording))
    assert result.stdout == expected


def test_frames_json_describes_the_recording(exported: Any) -> None:
    recording, layout, _ = exported
    doc = _doc(layout)
    with pcdcodec.open(recording) as rec:
        assert doc["format"] == "pcdcodec-paper-layout"
        assert doc["version"] == 1
        assert (doc["width"], doc["height"]) == (640, 480)
        assert doc["depth_dtype"] == "uint16"
        assert doc["depth_scale"] == rec.depth_scale == 5000.0
        assert doc["intrinsics"] == rec.intrinsics.to_dict()
        assert doc["fps"] == rec.fps
        assert doc["color_codec"] == rec.codecs["color"]
        assert doc["video_file"] == "color.mkv"
        assert doc["depth_file"] == "depth.lz4"
        assert doc["video"]["packets"] == FRAMES
        assert [e["index"] for e in doc["frames"]] == list(range(FRAMES))
        assert [e["timestamp_ns"] for e in doc["frames"]] == rec.timestamps.tolist()
    # Matroska counts milliseconds from the first frame: pts follow the timestamps.
    t0 = doc["video"]["time_origin_ns"]
    for e in doc["frames"]:
        assert abs(e["pts"] - (e["timestamp_ns"] - t0) / 1e6) <= 0.5


# -- import --------------------------------------------------------------------------------------


def test_import_round_trip_is_exact(imported: tuple[Path, Path]) -> None:
    original, back = imported
    a, b = _frames(original), _frames(back)
    assert len(a) == len(b) == FRAMES
    for x, y in zip(a, b, strict=True):
        assert x.timestamp_ns == y.timestamp_ns
        assert x.depth.dtype == y.depth.dtype
        assert np.array_equal(x.depth, y.depth)
        assert x.color is not None
        assert np.array_equal(x.color, y.color)


def test_import_does_not_reencode_color(imported: tuple[Path, Path]) -> None:
    original, back = imported
    assert _packets(back) == _packets(original)
    with pcdcodec.open(original) as a, pcdcodec.open(back) as b:
        assert b.codecs["color"] == a.codecs["color"]
        assert b.codecs["depth"]["id"] == pcdcodec.DEFAULT_DEPTH_CODEC
        assert b.intrinsics == a.intrinsics
        assert b.depth_scale == a.depth_scale
        assert b.fps == a.fps


def test_import_with_another_depth_codec(exported: Any, tmp_path: Path) -> None:
    recording, layout, _ = exported
    out = tmp_path / "lz4.pcdc"
    import_paper(layout, out, depth="lz4")
    with pcdcodec.open(out) as rec:
        assert rec.codecs["depth"]["id"] == "lz4"
    for x, y in zip(_frames(recording), _frames(out), strict=True):
        assert np.array_equal(x.depth, y.depth)


def test_import_without_codec_config_uses_the_defaults(exported: Any, tmp_path: Path) -> None:
    recording, layout, _ = exported
    copy = tmp_path / "layout"
    shutil.copytree(layout, copy)
    doc = _doc(copy)
    codec_id = doc.pop("color_codec")["id"]
    (copy / "frames.json").write_text(json.dumps(doc))
    out = tmp_path / "c.pcdc"
    import_paper(copy, out)
    with pcdcodec.open(out) as rec:
        assert rec.codecs["color"] == pcdcodec.get_codec(codec_id).stored_config()
    for x, y in zip(_frames(recording), _frames(out), strict=True):
        assert x.color is not None
        assert np.array_equal(x.color, y.color)


@pytest.mark.parametrize("color", OTHER_CODECS, ids=_codec_id)
def test_every_bitstream_round_trips(color: Any, tmp_path: Path) -> None:
    recording = _record(tmp_path / "a.pcdc", color)
    summary = export_paper(recording, tmp_path / "layout")
    video = tmp_path / "layout" / summary["video_file"]
    assert len(_decode_video(video)) == FRAMES
    import_paper(tmp_path / "layout", tmp_path / "b.pcdc")
    a, b = _frames(recording), _frames(tmp_path / "b.pcdc")
    assert [f.timestamp_ns for f in b] == [f.timestamp_ns for f in a]
    assert all(np.array_equal(x.depth, y.depth) for x, y in zip(a, b, strict=True))
    codec_id = color if isinstance(color, str) else color["id"]
    if codec_id != "h265":
        # hevc_mp4toannexb puts the parameter sets in front of the first packet once more.
        assert _packets(tmp_path / "b.pcdc") == _packets(recording)
    if codec_id != "mpeg4":
        # (MPEG-4 Part 2 decoding through Recording varies between runs in one process, for
        # the original as for the import; its packets are compared above instead.)
        for x, y in zip(a, b, strict=True):
            assert x.color is not None
            assert np.array_equal(x.color, y.color)


def test_float_depth_round_trips_bit_exactly(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=4)
    metres = []
    with pcdcodec.open(
        tmp_path / "f.pcdc",
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=1.0,
        color="ffv1",
        depth="lz4",
    ) as rec:
        for frame in seq:
            m = (frame.depth / seq.depth_scale).astype(np.float32)
            m[frame.depth == 0] = np.nan
            metres.append(m)
            rec.write(frame.color, m, frame.timestamp_ns)
    export_paper(tmp_path / "f.pcdc", tmp_path / "layout")
    doc = _doc(tmp_path / "layout")
    assert doc["depth_dtype"] == "float32"
    data = (tmp_path / "layout" / "depth.lz4").read_bytes()
    for entry, m in zip(doc["frames"], metres, strict=True):
        blob = data[entry["depth_offset"] : entry["depth_offset"] + entry["depth_length"]]
        assert lz4_frame.decompress(blob) == m.astype("<f4").tobytes()
    import_paper(tmp_path / "layout", tmp_path / "g.pcdc", depth="zstd")
    back = _frames(tmp_path / "g.pcdc")
    for frame, m in zip(back, metres, strict=True):
        assert frame.depth.dtype == np.float32
        assert np.array_equal(frame.depth.view(np.uint32), m.view(np.uint32))


def test_depth_only_recording_round_trips(tmp_path: Path) -> None:
    recording = _record(tmp_path / "d.pcdc", None)
    summary = export_paper(recording, tmp_path / "layout")
    assert summary["video_file"] is None
    assert sorted(p.name for p in (tmp_path / "layout").iterdir()) == ["depth.lz4", "frames.json"]
    doc = _doc(tmp_path / "layout")
    assert doc["video_file"] is None
    assert doc["color_codec"] is None
    import_paper(tmp_path / "layout", tmp_path / "e.pcdc")
    a, b = _frames(recording), _frames(tmp_path / "e.pcdc")
    assert all(y.color is None for y in b)
    assert all(np.array_equal(x.depth, y.depth) for x, y in zip(a, b, strict=True))


# -- errors --------------------------------------------------------------------------------------


@pytest.fixture
def h264_layout(tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> Path:
    """A fresh copy of an exported H.264 layout, free to damage."""
    cache = tmp_path_factory.getbasetemp() / "paper-errors-source"
    if not (cache / "layout").exists():
        cache.mkdir(exist_ok=True)
        export_paper(_record(cache / "a.pcdc", "h264"), cache / "layout")
    copy = tmp_path / "layout"
    shutil.copytree(cache / "layout", copy)
    return copy


def _edit(layout: Path, change: Any) -> None:
    doc = _doc(layout)
    change(doc)
    (layout / "frames.json").write_text(json.dumps(doc))


def test_export_refuses_a_non_empty_folder(exported: Any, tmp_path: Path) -> None:
    recording, _, _ = exported
    out = tmp_path / "out"
    out.mkdir()
    (out / "depth.lz4").write_bytes(b"old")
    with pytest.raises(InputError, match="not empty") as info:
        export_paper(recording, out)
    assert str(out) in str(info.value)
    assert (out / "depth.lz4").read_bytes() == b"old"
    (out / "color.avi").write_bytes(b"from an earlier export")
    export_paper(recording, out, overwrite=True)
    assert (out / "depth.lz4").read_bytes() != b"old"
    assert not (out / "color.avi").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_export_refuses_a_file_and_a_missing_recording(exported: Any, tmp_path: Path) -> None:
    recording, _, _ = exported
    (tmp_path / "file").write_bytes(b"")
    with pytest.raises(InputError, match="not a folder"):
        export_paper(recording, tmp_path / "file")
    with pytest.raises(InputError, match="does not exist"):
        export_paper(tmp_path / "nothing.pcdc", tmp_path / "out")


@pytest.mark.parametrize("name", ["frames.json", "depth.lz4", "color.mkv"])
def test_import_names_a_missing_file(h264_layout: Path, tmp_path: Path, name: str) -> None:
    (h264_layout / name).unlink()
    with pytest.raises(InputError, match=re.escape(name)):
        import_paper(h264_layout, tmp_path / "b.pcdc")
    assert not (tmp_path / "b.pcdc").exists()


def test_import_refuses_a_missing_folder_and_an_existing_output(
    h264_layout: Path, tmp_path: Path
) -> None:
    with pytest.raises(InputError, match="not a folder"):
        import_paper(tmp_path / "nowhere", tmp_path / "b.pcdc")
    (tmp_path / "b.pcdc").write_bytes(b"keep")
    with pytest.raises(InputError, match="already exists"):
        import_paper(h264_layout, tmp_path / "b.pcdc")
    assert (tmp_path / "b.pcdc").read_bytes() == b"keep"
    import_paper(h264_layout, tmp_path / "b.pcdc", overwrite=True)
    with pcdcodec.open(tmp_path / "b.pcdc") as rec:
        assert len(rec) == FRAMES


def test_import_reports_broken_json(h264_layout: Path, tmp_path: Path) -> None:
    (h264_layout / "frames.json").write_text('{"format": "pcdcodec-paper-layout", "frames": [')
    with pytest.raises(DecodeError, match=r"frames\.json.*not valid JSON"):
        import_paper(h264_layout, tmp_path / "b.pcdc")


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d.update(format="something else"), "format"),
        (lambda d: d.pop("depth_scale"), "depth_scale"),
        (lambda d: d.update(depth_dtype="int64"), "depth_dtype"),
        (lambda d: d.update(version=99), "version"),
        (lambda d: d["intrinsics"].pop("fx"), "intrinsics"),
        (lambda d: d.update(width=320), "intrinsics"),
        (lambda d: d.update(video_file="../color.mkv"), "video_file"),
        (lambda d: d.update(color_codec={"id": "ffv1"}), "color_codec"),
        (lambda d: d["frames"][2].update(depth_offset="x"), "frames[2].depth_offset"),
        (lambda d: d["frames"][3].pop("pts"), "frames[3].pts"),
        (lambda d: d["frames"][4].update(timestamp_ns=0), "frames[4].timestamp_ns"),
        (lambda d: d["frames"][5].update(index=7), "frames[5].index"),
        (lambda d: d["frames"][6].update(pts=d["frames"][5]["pts"]), "frames[6].pts"),
        (lambda d: d["video"].update(time_base=[1]), "video.time_base"),
        (lambda d: d["frames"][1].update(pose=[[2, 0, 0, 0]] * 4), "frames[1].pose"),
        (lambda d: d["frames"][1].update(depth_timestamp_ns=-1), "frames[1].depth_timestamp_ns"),
        (lambda d: d.update(metadata={"site": 3}), "metadata"),
        (lambda d: d.update(frame_id=""), "frame_id"),
        (lambda d: d.update(color_intrinsics={"width": 0}), "color_intrinsics"),
        (
            lambda d: d.update(color_intrinsics=d["intrinsics"], depth_to_color=None),
            "depth_to_color",
        ),
    ],
)
def test_import_names_the_malformed_field(
    h264_layout: Path, tmp_path: Path, change: Any, field: str
) -> None:
    _edit(h264_layout, change)
    with pytest.raises(DecodeError) as info:
        import_paper(h264_layout, tmp_path / "b.pcdc")
    assert "frames.json" in str(info.value)
    assert repr(field) in str(info.value)
    assert not (tmp_path / "b.pcdc").exists()


def test_import_reports_a_frame_count_mismatch(h264_layout: Path, tmp_path: Path) -> None:
    _edit(h264_layout, lambda d: d["frames"].pop())
    with pytest.raises(DecodeError, match="frame count mismatch") as info:
        import_paper(h264_layout, tmp_path / "b.pcdc")
    assert "color.mkv" in str(info.value)
    assert list(tmp_path.iterdir()) == [h264_layout]  # no recording, no temporary file


def test_import_reports_truncated_depth(h264_layout: Path, tmp_path: Path) -> None:
    data = (h264_layout / "depth.lz4").read_bytes()
    (h264_layout / "depth.lz4").write_bytes(data[: len(data) - 100])
    with pytest.raises(DecodeError, match=r"frame count mismatch.*depth\.lz4"):
        import_paper(h264_layout, tmp_path / "b.pcdc")


def test_import_reports_a_damaged_lz4_frame(h264_layout: Path, tmp_path: Path) -> None:
    entry = _doc(h264_layout)["frames"][3]
    data = bytearray((h264_layout / "depth.lz4").read_bytes())
    data[entry["depth_offset"] : entry["depth_offset"] + 4] = b"junk"  # the frame's magic
    (h264_layout / "depth.lz4").write_bytes(bytes(data))
    with pytest.raises(DecodeError, match=r"depth\.lz4.*frame 3.*not a valid LZ4 frame"):
        import_paper(h264_layout, tmp_path / "b.pcdc")
    assert not (tmp_path / "b.pcdc").exists()


def test_import_reports_a_video_that_is_not_one(h264_layout: Path, tmp_path: Path) -> None:
    (h264_layout / "color.mkv").write_bytes(b"not a video at all" * 10)
    with pytest.raises(DecodeError, match=r"color\.mkv"):
        import_paper(h264_layout, tmp_path / "b.pcdc")


@pytest.mark.parametrize("color", ["h264", None])
def test_poses_own_stamps_metadata_and_a_color_camera_apart_round_trip(
    tmp_path: Path, color: Any
) -> None:
    """What the video and the LZ4 depth cannot hold goes into frames.json and comes back: each
    frame's pose, the color and depth images' own times, the user's metadata, the frame id,
    and a color camera apart (of another size) with its depth_to_color."""
    seq = pcdcodec.load_sample(max_frames=4)
    cam = seq.intrinsics
    color_cam = pcdcodec.CameraIntrinsics(
        320, 240, 300.0, 301.0, 160.5, 119.5, "plumb_bob", (0.1, -0.02, 0.0, 0.001, 0.0)
    )
    d2c = np.eye(4)
    d2c[:3, 3] = [-0.025, 0.001, 0.0]
    path = tmp_path / "kept.pcdc"
    options: dict[str, Any] = {"color_intrinsics": color_cam, "depth_to_color": d2c}
    if color is None:
        options = {}
    with pcdcodec.open(
        path, "w", intrinsics=cam, depth_scale=seq.depth_scale, color=color, depth="zstd",
        metadata={"site": "lab", "run": "3"}, frame_id="head_depth", **options,
    ) as rec:  # fmt: skip
        for k, f in enumerate(seq):
            pose = None
            if k != 2:  # one frame without a pose
                pose = np.eye(4)
                pose[:3, 3] = [0.1 * k, -0.05 * k, 1.0]
            image = None if color is None else np.ascontiguousarray(f.color[::2, ::2])
            rec.write(
                image, f.depth, f.timestamp_ns, pose=pose,
                color_timestamp=None if color is None else f.timestamp_ns - 1000 * k,
                depth_timestamp=f.timestamp_ns + 36_000 + k,
            )  # fmt: skip
    export_paper(path, tmp_path / "layout")
    assert import_paper(tmp_path / "layout", tmp_path / "back.pcdc") == 4
    with pcdcodec.open(path) as a, pcdcodec.open(tmp_path / "back.pcdc") as b:
        assert b.metadata == a.metadata == {"site": "lab", "run": "3"}
        assert b.frame_id == "head_depth"
        assert b.color_intrinsics == a.color_intrinsics
        if color is None:
            assert b.depth_to_color is None
        else:
            assert b.color_intrinsics == color_cam
            assert b.depth_to_color is not None
            assert np.array_equal(b.depth_to_color, a.depth_to_color)
        for fa, fb in zip(a, b, strict=True):
            assert fb.timestamp_ns == fa.timestamp_ns
            assert fb.color_timestamp_ns == fa.color_timestamp_ns
            assert fb.depth_timestamp_ns == fa.depth_timestamp_ns
            assert fb.depth_timestamp_ns != fb.timestamp_ns
            assert np.array_equal(fb.depth, fa.depth)
            if fa.pose is None:
                assert fb.pose is None
            else:
                assert fb.pose is not None
                assert np.array_equal(fb.pose, fa.pose)
            if color is not None:
                assert fb.color is not None
                assert fa.color is not None
                assert fb.color.shape == (240, 320, 3)
                assert np.array_equal(fb.color, fa.color)
        assert sum(f.pose is not None for f in b) == 3
