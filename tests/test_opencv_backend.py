"""The OpenCV whole-file color backend (the paper's cv2.VideoWriter / cv2.VideoCapture path)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.color.opencv import FOURCCS, FileVideoCodec, OpenCVVideo
from pcdcodec.metrics import psnr

pytest.importorskip("cv2")

REPO = Path(__file__).resolve().parents[1]
SAMPLE_RGB = REPO / "pcdcodec" / "data" / "tum_fr1_rpy" / "rgb"
SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"

OPEN = list(OpenCVVideo.available_fourccs())
LOSSLESS = [f for f in OPEN if OpenCVVideo(fourcc=f).lossless]
LOSSY = [f for f in OPEN if not OpenCVVideo(fourcc=f).lossless]
#: Mean RGB PSNR (dB) on the 15 bundled frames, about 1.5 dB under what was measured with
#: opencv-python-headless 5.0 (MJPG 36.06, mp4v and XVID 34.44; docs/opencv-backend.md).
PSNR_FLOOR = {"MJPG": 34.5, "mp4v": 33.0, "XVID": 33.0}
SHARED = sorted(p.parent.name for p in SHARED_DATA.glob("*/rgb") if any(p.iterdir()))


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray[Any, Any]]:
    import imagecodecs

    paths = sorted(SAMPLE_RGB.glob("*.png"))
    assert len(paths) == 15
    return [np.asarray(imagecodecs.png_decode(p.read_bytes())) for p in paths]


def write(codec: OpenCVVideo, path: Path, frames: list[Any], fps: float = 30.0) -> Path:
    h, w = frames[0].shape[:2]
    with codec.writer(path, w, h, fps) as writer:
        for frame in frames:
            writer.write(frame)
    return writer.path


def read(codec: OpenCVVideo, path: Path) -> list[np.ndarray[Any, Any]]:
    with codec.reader(path) as reader:
        out = list(reader)
        assert len(reader) == len(out)
    return out


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# -- what opens here ---------------------------------------------------------------------------


def test_backend_is_available_and_the_paper_codecs_open() -> None:
    assert OpenCVVideo.is_available()
    assert OpenCVVideo.unavailable_reason() is None
    assert issubclass(OpenCVVideo, FileVideoCodec)
    # The lossless pair and MJPEG are the paper's main comparison; all of them must open.
    assert {"MJPG", "FFV1", "HFYU"} <= set(OPEN)
    assert set(OPEN) <= set(FOURCCS)


def test_lossless_only_for_ffv1_and_huffyuv() -> None:
    assert OpenCVVideo.lossless is False  # the class as a whole promises nothing
    assert {f for f in FOURCCS if OpenCVVideo(fourcc=f).lossless} == {"FFV1", "HFYU"}


def test_import_does_not_load_cv2() -> None:
    code = "import sys, pcdcodec.color.opencv; print('cv2' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# -- round trips -------------------------------------------------------------------------------


@pytest.mark.parametrize("fourcc", OPEN)
def test_frames_survive(fourcc: str, frames: list[Any], tmp_path: Path) -> None:
    codec = OpenCVVideo(fourcc=fourcc)
    path = write(codec, tmp_path / "color", frames, fps=12.5)
    assert path == tmp_path / f"color{codec.suffix}"
    with codec.reader(path) as reader:
        assert (reader.width, reader.height) == (640, 480)
        assert reader.fps == pytest.approx(12.5)
        assert len(reader) == len(frames)
        decoded = list(reader)
    assert len(decoded) == len(frames)
    assert all(d.shape == (480, 640, 3) and d.dtype == np.uint8 for d in decoded)
    if codec.lossless:
        for d, original in zip(decoded, frames, strict=True):
            np.testing.assert_array_equal(d, original)
    else:
        mean_psnr = float(np.mean([psnr(d, o) for d, o in zip(decoded, frames, strict=True)]))
        assert mean_psnr >= PSNR_FLOOR[fourcc], f"{fourcc}: {mean_psnr:.2f} dB"
        assert mean_psnr < 60  # lossy really is lossy
        # Channels come back in RGB order, not OpenCV's BGR: swapping them would cost far more.
        swapped = float(
            np.mean([psnr(d[..., ::-1], o) for d, o in zip(decoded, frames, strict=True)])
        )
        assert swapped < mean_psnr - 3


def test_every_lossy_fourcc_has_a_psnr_floor() -> None:
    assert set(LOSSY) <= set(PSNR_FLOOR)


@pytest.mark.parametrize("fourcc", LOSSLESS)
def test_lossless_bit_exact_on_noise_and_saturated_colors(fourcc: str, tmp_path: Path) -> None:
    # Noise and pure primaries are where any YUV or range conversion would show.
    rng = np.random.default_rng(7)
    noise = [rng.integers(0, 256, (64, 96, 3), dtype=np.uint8) for _ in range(3)]
    primaries = np.zeros((64, 96, 3), np.uint8)
    primaries[:, :32, 0] = 255
    primaries[:, 32:64, 1] = 255
    primaries[:, 64:, 2] = 255
    originals = [*noise, primaries]
    for container in (None, ".mkv"):
        codec = OpenCVVideo(fourcc=fourcc, container=container)
        decoded = read(codec, write(codec, tmp_path / f"n{container}", originals))
        assert len(decoded) == len(originals)
        for d, original in zip(decoded, originals, strict=True):
            np.testing.assert_array_equal(d, original)


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", SHARED or [pytest.param("none", marks=pytest.mark.skip)])
@pytest.mark.parametrize("fourcc", LOSSLESS)
def test_lossless_bit_exact_on_shared_sequences(fourcc: str, sequence: str, tmp_path: Path) -> None:
    import imagecodecs

    paths = sorted((SHARED_DATA / sequence / "rgb").iterdir())[:6]
    originals = [np.ascontiguousarray(imagecodecs.imread(str(p))[..., :3]) for p in paths]
    codec = OpenCVVideo(fourcc=fourcc)
    decoded = read(codec, write(codec, tmp_path / "seq", originals))
    assert len(decoded) == len(originals)
    for d, original in zip(decoded, originals, strict=True):
        np.testing.assert_array_equal(d, original)


def test_reader_iterates_again_from_the_start(frames: list[Any], tmp_path: Path) -> None:
    codec = OpenCVVideo(fourcc="FFV1")
    path = write(codec, tmp_path / "again.avi", frames[:4])
    reader = codec.reader(path)
    first = list(reader)
    second = list(reader)
    reader.close()
    third = list(reader)  # a closed reader opens the file again
    assert len(first) == len(second) == len(third) == 4
    for a, b, c in zip(first, second, third, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)


@pytest.mark.parametrize("fourcc", FOURCCS)
def test_config_round_trips_through_json(fourcc: str) -> None:
    for container in (None, ".mkv"):
        codec = OpenCVVideo(fourcc=fourcc, container=container)
        config = codec.get_config()
        assert config == {"id": "opencv", "fourcc": fourcc, "container": container}
        rebuilt = OpenCVVideo.from_config(json.loads(json.dumps(config)))
        assert isinstance(rebuilt, OpenCVVideo)
        assert rebuilt == codec
        assert repr(rebuilt) == repr(codec)
        assert rebuilt.lossless == codec.lossless


def test_default_containers() -> None:
    assert OpenCVVideo().suffix == ".avi"
    assert OpenCVVideo(fourcc="mp4v").suffix == ".mp4"
    assert OpenCVVideo(fourcc="HFYU", container=".mkv").suffix == ".mkv"


# -- what does not open ------------------------------------------------------------------------


def test_h264_is_unavailable_and_points_to_pyav(tmp_path: Path) -> None:
    if "avc1" in OPEN:
        pytest.skip("this OpenCV build writes H.264")
    codec = OpenCVVideo(fourcc="avc1")
    with pytest.raises(pcdcodec.CodecUnavailableError, match=r"'avc1'.*'h264'"):
        codec.writer(tmp_path / "color", 640, 480)
    assert leftovers(tmp_path) == []  # no empty or partial file is left behind


def test_container_that_cannot_hold_the_fourcc(tmp_path: Path) -> None:
    if OpenCVVideo.fourcc_available("HFYU", ".mp4"):
        pytest.skip("this OpenCV build puts HuffYUV into MP4")
    codec = OpenCVVideo(fourcc="HFYU", container=".mp4")
    with pytest.raises(pcdcodec.CodecUnavailableError, match=r"'HFYU'.*\.mp4.*container='\.avi'"):
        codec.writer(tmp_path / "color.mp4", 64, 48)
    assert leftovers(tmp_path) == []


def test_unknown_fourcc_allowed_only_when_it_opens(frames: list[Any], tmp_path: Path) -> None:
    with pytest.raises(pcdcodec.InputError, match="'ABCD'"):
        OpenCVVideo(fourcc="ABCD")
    if not OpenCVVideo.fourcc_available("H264"):
        with pytest.raises(pcdcodec.InputError, match=r"'H264'.*PyAV color codec 'h264'"):
            OpenCVVideo(fourcc="H264")
    if not OpenCVVideo.fourcc_available("DIVX"):
        pytest.skip("this OpenCV build does not write DIVX")
    codec = OpenCVVideo(fourcc="DIVX")  # FFmpeg's mpeg4 under another tag
    assert codec.suffix == ".mkv"
    assert not codec.lossless
    decoded = read(codec, write(codec, tmp_path / "divx", frames[:3]))
    assert len(decoded) == 3
    assert psnr(decoded[1], frames[1]) > PSNR_FLOOR["mp4v"]


@pytest.mark.parametrize(
    ("params", "error", "match"),
    [
        ({"fourcc": "MJPEG"}, pcdcodec.InputError, "4 printable ASCII characters, got 'MJPEG'"),
        ({"fourcc": "MJ\u00e9G"}, pcdcodec.InputError, "4 printable ASCII"),
        ({"fourcc": 1196444237}, pcdcodec.InputTypeError, "got int"),
        ({"container": ".webm"}, pcdcodec.InputError, "got '.webm'"),
        ({"container": "avi"}, pcdcodec.InputError, "got 'avi'"),
        ({"quality": 90}, pcdcodec.InputError, "no parameter 'quality'"),
    ],
)
def test_bad_parameters(params: dict[str, Any], error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        OpenCVVideo.from_config({"id": "opencv", **params})


# -- bad input ---------------------------------------------------------------------------------


def test_bad_frames_are_refused_and_the_good_ones_kept(frames: list[Any], tmp_path: Path) -> None:
    codec = OpenCVVideo(fourcc="FFV1")
    with codec.writer(tmp_path / "bad.avi", 640, 480) as writer:
        writer.write(frames[0])
        with pytest.raises(pcdcodec.InputTypeError, match="uint8, got float32"):
            writer.write(frames[1].astype(np.float32))
        with pytest.raises(pcdcodec.InputError, match="RGBA"):
            writer.write(np.dstack([frames[1], np.full((480, 640), 255, np.uint8)]))
        with pytest.raises(pcdcodec.InputError, match=r"shape \(height, width, 3\)"):
            writer.write(frames[1][..., 0])
        with pytest.raises(pcdcodec.InputError, match="cannot change mid-file"):
            writer.write(frames[1][:240, :320])
        writer.write(frames[1])
    assert writer.frames_written == 2
    decoded = read(codec, writer.path)
    assert len(decoded) == 2
    np.testing.assert_array_equal(decoded[1], frames[1])
    with pytest.raises(pcdcodec.InputError, match="closed"):
        writer.write(frames[2])


@pytest.mark.parametrize(
    ("size", "fps", "match"),
    [
        ((641, 480), 30.0, "even width and height, got 641x480"),
        ((640, 479), 30.0, "even width and height, got 640x479"),
        ((0, 480), 30.0, "width must be in 1..16384"),
        ((640, 480), 0, "fps must be a number in"),
        ((640, 480), float("nan"), "fps must be a number in"),
    ],
)
def test_bad_writer_arguments(
    size: tuple[int, int], fps: float, match: str, tmp_path: Path
) -> None:
    with pytest.raises(pcdcodec.InputError, match=match):
        OpenCVVideo().writer(tmp_path / "x", *size, fps)
    assert leftovers(tmp_path) == []


def test_wrong_extension_is_refused(tmp_path: Path) -> None:
    with pytest.raises(pcdcodec.InputError, match=r"ends in '\.mp4'.*\.avi"):
        OpenCVVideo(fourcc="MJPG").writer(tmp_path / "color.mp4", 64, 48)
    with pytest.raises(pcdcodec.InputError, match="does not exist"):
        OpenCVVideo().writer(tmp_path / "missing" / "color.avi", 64, 48)


def test_existing_file_is_not_overwritten(frames: list[Any], tmp_path: Path) -> None:
    path = tmp_path / "color.avi"
    path.write_bytes(b"keep me")
    codec = OpenCVVideo(fourcc="FFV1")
    with pytest.raises(pcdcodec.InputError, match=r"color\.avi' already exists.*overwrite=True"):
        codec.writer(path, 640, 480)
    assert path.read_bytes() == b"keep me"
    assert leftovers(tmp_path) == ["color.avi"]
    write_over = codec.writer(path, 640, 480, overwrite=True)
    with write_over as writer:
        writer.write(frames[0])
        assert path.read_bytes() == b"keep me"  # replaced only when closed
    np.testing.assert_array_equal(read(codec, path)[0], frames[0])


def test_failed_recording_leaves_no_file(frames: list[Any], tmp_path: Path) -> None:
    codec = OpenCVVideo()
    path = tmp_path / "color.avi"

    def record_then_fail() -> None:
        with codec.writer(path, 640, 480) as writer:
            writer.write(frames[0])
            raise RuntimeError("camera died")

    def record_nothing() -> None:
        with codec.writer(path, 640, 480):
            pass

    with pytest.raises(RuntimeError, match="camera died"):
        record_then_fail()
    assert leftovers(tmp_path) == []
    with pytest.raises(pcdcodec.InputError, match="no frames were written"):
        record_nothing()
    assert leftovers(tmp_path) == []


def test_reader_errors_name_the_path(frames: list[Any], tmp_path: Path) -> None:
    codec = OpenCVVideo()
    with pytest.raises(pcdcodec.InputError, match=r"nope\.avi' does not exist"):
        codec.reader(tmp_path / "nope.avi")
    with pytest.raises(pcdcodec.InputError, match="is a folder"):
        codec.reader(tmp_path)
    garbage = tmp_path / "garbage.avi"
    garbage.write_bytes(np.random.default_rng(3).bytes(5000))
    with pytest.raises(pcdcodec.DecodeError, match=r"garbage\.avi' is not a video"):
        codec.reader(garbage)
    # A file cut short: the frames still there decode, then the shortfall is an error.
    path = write(codec, tmp_path / "cut.avi", frames[:8])
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    reader = codec.reader(path)
    assert len(reader) == 8  # what the file's header declares
    got: list[np.ndarray[Any, Any]] = []
    with pytest.raises(pcdcodec.DecodeError, match=r"cut\.avi' declares 8 frames, but \d"):
        got.extend(reader)
    assert 0 < len(got) < 8
