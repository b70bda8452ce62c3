"""The Azure Kinect .mkv reader, on a real k4arecorder file (skipped when it is absent)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import DecodeError, InputError
from pcdcodec.sources.azure_kinect import AzureKinectSource

from .conftest import SHARED_DATA

MKV = SHARED_DATA / "bags" / "pyk4a_recording.mkv"
needs_mkv = pytest.mark.skipif(not MKV.exists(), reason=f"{MKV} is not present")


@needs_mkv
def test_reads_depth_color_and_both_cameras() -> None:
    import av

    with pcdcodec.open_source(MKV) as src:
        assert isinstance(src, AzureKinectSource)
        assert src.metadata["serial"] == "001514394512"
        assert src.metadata["depth_mode"] == "NFOV_UNBINNED"
        frames = list(src)
        intr, color = src.intrinsics, src.color_intrinsics
        d2c = src.depth_to_color
        assert src.dropped == {"color": 0, "depth": 0}
        assert src.damage is None  # its 4 blocks (IMU, color, depth, IR) all read
    assert intr is not None
    assert color is not None
    # The SDK's mode-specific rule: scale to the binned sensor, crop (192, 180), centre pixels.
    assert intr.shape == (576, 640)
    assert intr.fx == pytest.approx(0.4927808940410614 * 1024)
    assert intr.cx == pytest.approx(0.5129697918891907 * 1024 - 192 - 0.5)
    assert intr.cy == pytest.approx(0.5169235467910767 * 1024 - 180 - 0.5)
    assert intr.distortion_model == "rational_polynomial"
    assert color.shape == (720, 1280)
    assert color.fy == pytest.approx(0.6374239325523376 * 960)
    assert color.cy == pytest.approx(0.5066176056861877 * 960 - 120 - 0.5)
    assert d2c[0, 3] == pytest.approx(-0.032083429396152496)  # metres, depth -> color
    assert len(frames) == 1
    f = frames[0]
    # Depth is the DEPTH track's packet, read as big-endian 16-bit, untouched.
    with av.open(str(MKV)) as c:
        stream = next(s for s in c.streams if s.metadata.get("title") == "DEPTH")
        raw = next(bytes(p) for p in c.demux(stream) if p.size)
    assert np.array_equal(f.depth, np.frombuffer(raw, ">u2").reshape(576, 640))
    assert f.color.shape == (720, 1280, 3)
    assert (f.depth == 0).mean() == pytest.approx(0.235, abs=0.005)
    assert np.median(f.depth[f.depth > 0]) == pytest.approx(1491, abs=5)
    proj = pcdcodec.Projector(intr, 1000.0, color_intrinsics=color, depth_to_color=d2c)
    points, colors = proj.to_points(f.depth, f.color)
    assert colors is not None
    assert points.shape[0] == int((f.depth > 0).sum())
    assert (colors.sum(axis=1) > 0).mean() > 0.9  # most points fall inside the color image


def _variant(tmp_path: Path, old: bytes, new: bytes) -> Path:
    data = MKV.read_bytes()
    assert data.count(old) >= 1
    out = tmp_path / "variant.mkv"
    out.write_bytes(data.replace(old, new))
    return out


@needs_mkv
def test_unknown_depth_mode(tmp_path: Path) -> None:
    path = _variant(tmp_path, b"NFOV_UNBINNED", b"NFOV_SUPERXXX")
    with pytest.raises(InputError, match="depth mode 'NFOV_SUPERXXX'; expected one of"):
        pcdcodec.open_source(path)


@needs_mkv
def test_missing_calibration(tmp_path: Path) -> None:
    path = _variant(tmp_path, b"calibration.json", b"calibratiox.json")
    with pytest.raises(InputError, match=r"no calibration\.json attachment"):
        pcdcodec.open_source(path)


@needs_mkv
def test_no_clusters(tmp_path: Path) -> None:
    data = MKV.read_bytes()
    path = tmp_path / "cut.mkv"
    path.write_bytes(data[: data.find(b"\x1f\x43\xb6\x75")])
    with pytest.raises(InputError, match="holds no clusters"):
        pcdcodec.open_source(path)


@needs_mkv
def test_cli_encodes_a_camera_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from pcdcodec.cli import main

    out = tmp_path / "ak.pcdc"
    assert main(["encode", str(MKV), "-o", str(out), "--color", "ffv1"]) == 0
    assert "depth scale  1000 units per metre" in capsys.readouterr().out
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format_version"] == 4  # a color camera apart (2), and kept tracks (4)
    assert info["color_intrinsics"]["width"] == 1280
    assert info["intrinsics"]["distortion_model"] == "rational_polynomial"
    assert info["metadata"]["serial"] == "001514394512"
    with pcdcodec.open(out) as rec, pcdcodec.open_source(MKV) as src:
        (original,) = list(src)
        assert np.array_equal(rec[0].depth, original.depth)
        assert np.array_equal(rec[0].color, original.color)  # ffv1: lossless


# -- small k4arecorder-like files, written element by element (tests/camera_file_fuzz.py) ----


def _mkv(tmp_path: Path, change: Any = None, captures: int = 3, name: str = "small.mkv") -> Path:
    """A recording of ``captures`` captures (MJPEG 1280x720, depth 320x288), ``change(spec)``
    applied first."""
    from .camera_file_fuzz import mkv_spec

    spec = mkv_spec(captures)
    if change is not None:
        change(spec)
    path = tmp_path / name
    path.write_bytes(spec.to_bytes())
    return path


def _drop_block(capture: int, track: int) -> Any:
    def change(spec: Any) -> None:
        blocks = spec.clusters[capture][1]
        blocks[:] = [b for b in blocks if not (b[0] == 0xA3 and b[1][0] & 0x7F == track)]

    return change


def test_small_recording_reads_exactly(tmp_path: Path) -> None:
    import av

    from .camera_file_fuzz import mkv_spec

    spec = mkv_spec(3)
    with AzureKinectSource(_mkv(tmp_path)) as src:
        frames = list(src)
        assert src.dropped == {"color": 0, "depth": 0}
    assert [f.timestamp_ns for f in frames] == [336_277_000 + k * 33_333_000 for k in range(3)]
    for f, cluster in zip(frames, spec.clusters, strict=True):
        jpeg, depth = (el[1][4:] for el in cluster[1] if el[0] == 0xA3)
        assert np.array_equal(f.depth, np.frombuffer(depth, ">u2").reshape(288, 320))
        (decoded,) = av.CodecContext.create("mjpeg", "r").decode(av.Packet(jpeg))
        assert np.array_equal(f.color, decoded.to_ndarray(format="rgb24"))


@pytest.mark.parametrize(("track", "stream"), [(1, "depth"), (2, "color")])
def test_capture_missing_an_image_is_reported(tmp_path: Path, track: int, stream: str) -> None:
    """A capture without its color (track 1) or depth (track 2) block: the other image is
    dropped, counted in ``dropped`` and ``summary.dropped``, and its reason in the notes."""
    path = _mkv(tmp_path, _drop_block(1, track))
    with AzureKinectSource(path) as src:
        assert len(list(src)) == 2
        assert src.dropped == {"color": int(stream == "color"), "depth": int(stream == "depth")}
        (note,) = src.describe()["notes"]
    other = "color" if stream == "depth" else "depth"
    assert f"dropped 1 capture(s): a {stream} image without its {other} image" in note
    summary = pcdcodec.encode(path, tmp_path / "out.pcdc", color="ffv1")
    assert summary.frames == 2
    assert summary.dropped == src.dropped


def test_unpaired_images_pushed_out_are_counted(tmp_path: Path) -> None:
    """Ten captures whose first seven lack color: the reader keeps only a few unpaired images
    waiting, and every one it lets go is counted."""

    def change(spec: Any) -> None:
        for k in range(7):
            _drop_block(k, 1)(spec)

    with AzureKinectSource(_mkv(tmp_path, change, captures=10)) as src:
        assert len(list(src)) == 3
        assert src.dropped == {"color": 0, "depth": 7}
        assert src.drop_reasons == {"a depth image without its color image": 7}


def _cut_color(capture: int) -> Any:
    def change(spec: Any) -> None:
        block = next(b for b in spec.clusters[capture][1] if b[0] == 0xA3)
        block[1] = block[1][: len(block[1]) // 2]

    return change


def test_truncated_mjpeg_is_dropped_and_reported(tmp_path: Path) -> None:
    """Half an MJPEG image decodes to a partly grey image without an error in FFmpeg; the
    reader checks each packet first and drops the capture, saying why."""
    path = _mkv(tmp_path, _cut_color(1))
    with AzureKinectSource(path) as src:
        frames = list(src)
        notes = src.describe()["notes"]
    assert len(frames) == 2
    assert src.dropped == {"color": 1, "depth": 1}
    assert src.drop_reasons == {"damaged color": 1}
    assert "damaged color (first at pts 33333): color packet at pts 33333: the JPEG" in notes[0]
    with pytest.raises(DecodeError, match=r"color packet at pts 33333: the JPEG image is cut"):
        list(AzureKinectSource(path, strict=True))


def test_wrong_depth_size_is_dropped_or_an_error(tmp_path: Path) -> None:
    def change(spec: Any) -> None:
        block = [b for b in spec.clusters[2][1] if b[0] == 0xA3][1]
        block[1] = block[1][:-2]

    path = _mkv(tmp_path, change)
    with AzureKinectSource(path) as src:
        assert len(list(src)) == 2
        assert src.dropped == {"color": 1, "depth": 1}
    with pytest.raises(DecodeError, match=r"small.mkv.*depth packet at pts 66666 holds 184318"):
        list(AzureKinectSource(path, strict=True))


def _calibration(change_camera: Any) -> Any:
    def change(spec: Any) -> None:
        cameras = spec.calibration["CalibrationInformation"]["Cameras"]
        change_camera(cameras[0], cameras[1])

    return change


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (
            lambda d, c: d["Intrinsics"]["ModelParameters"].__setitem__(2, "0.5"),
            r"depth camera Intrinsics.ModelParameters\[2\] is '0.5'; expected a finite number",
        ),
        (
            lambda d, c: d["Intrinsics"]["ModelParameters"].__setitem__(5, None),
            r"ModelParameters\[5\] is None",
        ),
        (
            lambda d, c: d["Intrinsics"].__setitem__("ModelParameters", None),
            r"depth camera calibration has None model parameters",
        ),
        (
            lambda d, c: c["Rt"].__setitem__("Rotation", [1.0, 0.0, 0.0]),
            r"color camera Rt.Rotation holds 3 values; expected a list of 9 numbers",
        ),
        (
            lambda d, c: c["Rt"].__setitem__("Rotation", [2.0, 0, 0, 0, 1, 0, 0, 0, 1]),
            r"Rt.Rotation .* is not a rotation matrix",
        ),
        (lambda d, c: c.pop("Rt"), r"calibration.json.Rt is missing"),
        (lambda d, c: c.__setitem__("SensorWidth", "4096"), r"SensorWidth/SensorHeight"),
        (
            lambda d, c: d["Intrinsics"]["ModelParameters"].__setitem__(0, -1.0),
            r"depth camera Intrinsics: cx must lie in the image",
        ),
    ],
)
def test_bad_calibration_names_the_file_and_field(tmp_path: Path, change: Any, match: str) -> None:
    path = _mkv(tmp_path, _calibration(change))
    with pytest.raises(InputError, match=match) as info:
        AzureKinectSource(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("value", ["abc", "-5", "1e9", "99999999999999999999999"])
def test_bad_start_offset_names_the_tag(tmp_path: Path, value: str) -> None:
    def change(spec: Any) -> None:
        spec.tags["K4A_START_OFFSET_NS"] = value

    path = _mkv(tmp_path, change)
    with pytest.raises(InputError, match=r"tag K4A_START_OFFSET_NS is .*whole number") as info:
        AzureKinectSource(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("private", [b"", b"(\x00\x00\x00"])
def test_empty_color_codec_private_is_refused(tmp_path: Path, private: bytes) -> None:
    def change(spec: Any) -> None:
        next(el for el in spec.tracks[0][1] if el[0] == 0x63A2)[1] = private

    path = _mkv(tmp_path, change)
    with pytest.raises(InputError, match=r"COLOR track") as info:
        AzureKinectSource(path)
    assert str(path) in str(info.value)


def test_unreadable_color_track_is_refused_not_left_out(tmp_path: Path) -> None:
    """FFmpeg leaves out a track without a CodecID, and its tags with it: the file still
    declares a color mode, so reading it as depth only would lose the color silently."""

    def change(spec: Any) -> None:
        next(el for el in spec.tracks[0][1] if el[0] == 0x86)[1] = b""

    with pytest.raises(InputError, match=r"declares a color mode .* does not read"):
        AzureKinectSource(_mkv(tmp_path, change))


def test_track_roles_come_from_the_mode_tags(tmp_path: Path) -> None:
    """A COLOR track named DEPTH: its K4A_COLOR_MODE tag says what it is."""

    def change(spec: Any) -> None:
        next(el for el in spec.tracks[0][1] if el[0] == 0x536E)[1] = b"DEPTH"

    with AzureKinectSource(_mkv(tmp_path, change)) as src:
        frames = list(src)
    assert len(frames) == 3
    assert frames[0].color is not None
    assert frames[0].color.shape == (720, 1280, 3)


def test_tags_that_are_not_text(tmp_path: Path) -> None:
    from .camera_file_fuzz import mkv_spec

    spec = mkv_spec(1)
    data = spec.to_bytes().replace(b"000000000000", b"00000\xb7\xb7\xb70000")
    path = tmp_path / "latin.mkv"
    path.write_bytes(data)
    with pytest.raises(InputError, match=r"not UTF-8") as info:
        AzureKinectSource(path)
    assert str(path) in str(info.value)


def test_cli_encode_prints_why_captures_were_dropped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    path = _mkv(tmp_path, _cut_color(1))
    out = tmp_path / "out.pcdc"
    assert main(["encode", str(path), "-o", str(out), "--color", "ffv1"]) == 0
    printed = capsys.readouterr().out
    assert "wrote 2 frames" in printed
    assert "dropped      1 color and 1 depth" in printed
    assert "note         dropped 1 capture(s): damaged color (first at pts 33333)" in printed


def test_file_cut_short_is_reported(tmp_path: Path) -> None:
    """A recording cut in its last capture: FFmpeg stops at the cut without a word; the reader
    compares the blocks the clusters hold with the packets read, and says what was lost."""
    whole = _mkv(tmp_path)
    data = whole.read_bytes()
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(data[: data.rfind(b"\x1f\x43\xb6\x75") + 300])  # inside the last cluster
    with AzureKinectSource(cut) as src:
        assert len(list(src)) == 2
        assert src.damage is not None
        assert "cut short: its Segment declares" in src.damage
        assert src.damage in src.describe()["notes"]
    with pytest.raises(DecodeError, match=r"cut.mkv'?: the file is damaged: it is cut short"):
        list(AzureKinectSource(cut, strict=True))


def test_damaged_cluster_is_reported(tmp_path: Path) -> None:
    """A cluster whose size says 1 byte: FFmpeg skips the rest of it silently."""

    def change(spec: Any) -> None:
        spec.clusters[1].append(None)  # size override slot
        spec.clusters[1][2] = 1

    path = _mkv(tmp_path, change)
    with AzureKinectSource(path) as src:
        frames = list(src)
        assert len(frames) < 3
        assert src.damage is not None
        assert "the file is damaged" in src.damage


@pytest.mark.parametrize(
    "new_id", [0x1654AE6B, 0x1549A966, 0x1941A469, 0x1254C367, 0x1C53BB6B, 0xEC]
)
def test_cluster_whose_id_became_another_element_is_reported(tmp_path: Path, new_id: int) -> None:
    """A damaged Cluster ID that names another top-level element (a second Tracks, a Void...):
    FFmpeg skips it as that element, and its capture would vanish without a word."""

    def change(spec: Any) -> None:
        spec.clusters[1][0] = new_id

    with AzureKinectSource(_mkv(tmp_path, change)) as src:
        assert len(list(src)) == 2
        assert src.damage is not None
        assert "the element at byte" in src.damage


@pytest.mark.parametrize(("fourcc", "bits", "nbytes"), [(b"YUY2", 16, 2), (b"NV12", 12, 1.5)])
def test_raw_color_is_read_and_its_length_checked(
    tmp_path: Path, fourcc: bytes, bits: int, nbytes: float
) -> None:
    """The raw color modes (YUY2, NV12): mid grey reads as mid grey; a packet of another length
    is a damaged image, dropped and reported."""
    from .camera_file_fuzz import _bih

    size = int(1280 * 720 * nbytes)

    def change(spec: Any) -> None:
        next(el for el in spec.tracks[0][1] if el[0] == 0x63A2)[1] = _bih(
            1280, 720, bits, fourcc, size
        )
        for k, cluster in enumerate(spec.clusters):
            block = next(b for b in cluster[1] if b[0] == 0xA3)
            payload = bytes([128]) * (size - (k == 2))  # the last one a byte short
            block[1] = block[1][:4] + payload

    with AzureKinectSource(_mkv(tmp_path, change)) as src:
        frames = list(src)
        assert src.drop_reasons == {"damaged color": 1}
    assert len(frames) == 2
    assert frames[0].color is not None
    assert frames[0].color.shape == (720, 1280, 3)
    assert np.abs(frames[0].color.astype(int) - 128).max() <= 2
