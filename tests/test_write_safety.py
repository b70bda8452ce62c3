"""Writes fail early and lose nothing; folders are never read with a guessed depth scale."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

import pcdcodec
from pcdcodec.color import PyAVCodec, StreamCodec
from pcdcodec.datasets import RGBDSequence, load_folder, load_sample, sample_dir
from pcdcodec.depth import Zstd
from pcdcodec.errors import InputError, InputTypeError
from pcdcodec.recording.writer import MAX_TIMESTAMP_NS


@pytest.fixture(scope="module")
def sample() -> RGBDSequence:
    return load_sample(max_frames=10)


def _open(path: Path, sample: RGBDSequence, **options: Any) -> pcdcodec.RecordingWriter:
    options.setdefault("depth", "zstd")
    return pcdcodec.open(
        path, "w", intrinsics=sample.intrinsics, depth_scale=sample.depth_scale, **options
    )


# -- timestamps the container cannot hold -------------------------------------------------------


def test_a_timestamp_past_2038_is_refused_at_write_and_nothing_is_lost(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "late.pcdc"
    good = MAX_TIMESTAMP_NS - 10 * 33_000_000
    with _open(path, sample) as rec:
        for i in range(5):
            rec.write(sample[i].color, sample[i].depth, good + i * 33_000_000)
        too_late = MAX_TIMESTAMP_NS + 1
        with pytest.raises(
            InputError, match=rf"{too_late} ns is later.*at most {MAX_TIMESTAMP_NS}"
        ):
            rec.write(sample[5].color, sample[5].depth, too_late)
        rec.write(sample[5].color, sample[5].depth, MAX_TIMESTAMP_NS)  # the limit itself fits
    with pcdcodec.open(path) as back:
        assert back.indexed
        assert len(back) == 6
        assert int(back.timestamps[-1]) == MAX_TIMESTAMP_NS
        for i, frame in enumerate(back):
            np.testing.assert_array_equal(frame.depth, sample[i].depth)
        assert back.verify().ok


# -- close() never makes written frames unreadable --------------------------------------------


class _FailingZstd(Zstd):
    """zstd that fails on one call, as a codec might on a bad frame or a full memory."""

    def __init__(self, fail_on: int) -> None:
        super().__init__()
        self._calls = 0
        self._fail_on = fail_on

    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        return ("level",)  # the file records plain zstd, which reads it back

    def encode(self, depth: npt.ArrayLike) -> bytes:
        self._calls += 1
        if self._calls == self._fail_on:
            raise RuntimeError(f"encoder failure on call {self._calls}")
        return super().encode(depth)


def test_a_frame_failing_in_the_background_keeps_every_other_frame(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "failing.pcdc"
    rec = _open(path, sample, depth=_FailingZstd(fail_on=9), in_flight=4)
    for i in range(9):
        rec.write(sample[i].color, sample[i].depth, i * 33_000_000)
    # Frame 8 fails in the background; no write() follows, so close() raises it.
    with pytest.raises(RuntimeError, match="call 9"):
        rec.close()
    with pcdcodec.open(path) as back:
        assert back.indexed  # the index was still written
        kept = [int(t) // 33_000_000 for t in back.timestamps]
        assert kept == [0, 1, 2, 3, 4, 5, 6, 7]
        for frame, i in zip(back, kept, strict=True):
            np.testing.assert_array_equal(frame.depth, sample[i].depth)
            assert frame.color is not None
        assert back.verify().ok


def test_a_failing_index_write_keeps_every_frame_readable(
    tmp_path: Path, sample: RGBDSequence, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "noindex.pcdc"
    rec = _open(path, sample)
    for i in range(10):
        rec.write(sample[i].color, sample[i].depth, i * 33_000_000)

    def disk_full() -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(rec._mcap, "finish", disk_full)
    with pytest.raises(OSError, match="No space left"):
        rec.close()
    with pcdcodec.open(path) as back:
        assert not back.indexed
        # The encoder was still flushed: every frame, even those x264 held back, is there.
        assert len(back) == 10
        for i, frame in enumerate(back):
            np.testing.assert_array_equal(frame.depth, sample[i].depth)


def test_close_ends_when_a_step_fails_without_taking_its_frame(
    tmp_path: Path, sample: RGBDSequence, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "stuck.pcdc"

    def full(self: Any) -> None:  # fails before taking the frame off the queue
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pcdcodec.RecordingWriter, "_drain_one", full)
    rec = _open(path, sample, in_flight=4)
    rec.write(sample[0].color, sample[0].depth, 0)
    with pytest.raises(OSError, match="No space left"):
        rec.flush()  # the frame got its one try and the queue moved on
    rec.write(sample[1].color, sample[1].depth, 33_000_000)
    with pytest.raises(OSError, match="No space left"):
        rec.close()  # one try per queued frame, then the index: it ends
    with pcdcodec.open(path) as back:
        assert back.indexed
        assert len(back) == 0


def test_a_failed_replacement_keeps_the_old_file(tmp_path: Path, sample: RGBDSequence) -> None:
    path = tmp_path / "old.pcdc"
    with _open(path, sample) as rec:
        rec.write(sample[0].color, sample[0].depth, 0)
    before = path.read_bytes()
    rec = _open(path, sample, overwrite=True, depth=_FailingZstd(fail_on=2))
    rec.write(sample[0].color, sample[0].depth, 0)
    rec.write(sample[1].color, sample[1].depth, 1)
    with pytest.raises(RuntimeError) as info:
        rec.close()
    assert path.read_bytes() == before
    partial = [p for p in tmp_path.iterdir() if p.name.startswith(".old.pcdc.partial")]
    assert len(partial) == 1
    if sys.version_info >= (3, 11):  # exception notes
        assert str(partial[0]) in "\n".join(getattr(info.value, "__notes__", []))


# -- a failing constructor leaves nothing behind ----------------------------------------------


def test_a_bad_frame_id_is_an_input_error_and_leaves_no_file(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    path = tmp_path / "x.pcdc"
    with pytest.raises(InputTypeError, match="frame_id must be a str, got 123"):
        _open(path, sample, frame_id=123)
    assert not path.exists()
    with _open(path, sample, frame_id="cam0") as rec:  # the retry works
        rec.write(sample[0].color, sample[0].depth, 0)
    assert path.exists()


def test_a_constructor_failing_after_opening_the_file_removes_it(
    tmp_path: Path, sample: RGBDSequence, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(self: Any, user: Any) -> None:
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(pcdcodec.RecordingWriter, "_start", broken)
    path = tmp_path / "x.pcdc"
    with pytest.raises(OSError, match="Input/output"):
        _open(path, sample)
    assert list(tmp_path.iterdir()) == []
    path.write_bytes(b"keep me")
    with pytest.raises(OSError, match="Input/output"):
        _open(path, sample, overwrite=True)
    assert list(tmp_path.iterdir()) == [path]  # the partial file is gone, the old one stays
    assert path.read_bytes() == b"keep me"


@pytest.mark.parametrize(
    ("metadata", "error", "match"),
    [
        ({"k": object()}, InputError, r"metadata\['k'\] = <object object"),
        ({"k": {"nested": {1, 2}}}, InputError, r"metadata\['k'\]"),
        ({"k": float("nan")}, InputError, r"metadata\['k'\] = nan"),
        ({3: "x"}, InputTypeError, "metadata key 3 must be a str"),
        (["k"], InputTypeError, "metadata must be a dict, got list"),
    ],
)
def test_metadata_that_cannot_be_stored_names_the_key(
    tmp_path: Path, sample: RGBDSequence, metadata: Any, error: type[Exception], match: str
) -> None:
    path = tmp_path / "m.pcdc"
    with pytest.raises(error, match=match):
        _open(path, sample, metadata=metadata)
    assert not path.exists()


def test_metadata_values_are_kept(tmp_path: Path, sample: RGBDSequence) -> None:
    path = tmp_path / "m.pcdc"
    with _open(path, sample, metadata={"site": "lab", "run": 3, "tags": ["a", "b"]}) as rec:
        rec.write(sample[0].color, sample[0].depth, 0)
    with pcdcodec.open(path) as back:
        assert back.metadata == {"site": "lab", "run": "3", "tags": '["a", "b"]'}


# -- nothing is dropped or guessed silently ---------------------------------------------------


def test_color_given_to_a_depth_only_recording_is_refused(
    tmp_path: Path, sample: RGBDSequence
) -> None:
    with _open(tmp_path / "d.pcdc", sample, color=None) as rec:
        with pytest.raises(InputError, match="depth only"):
            rec.write(sample[0].color, sample[0].depth, 0)
        rec.write(None, sample[0].depth, 0)
    with pcdcodec.open(tmp_path / "d.pcdc") as back:
        assert len(back) == 1


def _tum_copy(tmp_path: Path, *, camera: bool, tum_header: bool = True) -> Path:
    root = tmp_path / "tum"
    shutil.copytree(sample_dir(), root)
    if not camera:
        (root / "camera.json").unlink()
    if not tum_header:
        lines = (root / "depth.txt").read_text().splitlines()
        lines[1] = "# file: 'my own camera'"
        (root / "depth.txt").write_text("\n".join(lines) + "\n")
    return root


def test_a_tum_dataset_folder_without_camera_json_gets_tums_scale(tmp_path: Path) -> None:
    seq = load_folder(_tum_copy(tmp_path, camera=False), max_frames=2)
    assert seq.depth_scale == 5000.0
    source = pcdcodec.datasets.open_folder(tmp_path / "tum", max_frames=1)
    assert source.depth_scale_origin == "TUM RGB-D dataset"
    assert load_folder(tmp_path / "tum", max_frames=1, depth_scale=1000.0).depth_scale == 1000.0


def test_a_folder_that_does_not_say_its_scale_is_refused(tmp_path: Path) -> None:
    root = _tum_copy(tmp_path, camera=False, tum_header=False)
    with pytest.raises(InputError, match=r"no depth scale.*pass depth_scale=UNITS_PER_METRE"):
        load_folder(root)
    assert load_folder(root, max_frames=1, depth_scale=1000.0).depth_scale == 1000.0


def test_the_bundled_sample_keeps_its_scale() -> None:
    assert load_sample(max_frames=1).depth_scale == 5000.0
    source = pcdcodec.datasets.open_folder(sample_dir(), max_frames=1)
    assert source.depth_scale_origin == "camera.json"


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pcdcodec", *args], capture_output=True, text=True, timeout=300
    )


def test_cli_encode_of_a_tum_folder_prints_the_scale_and_camera_used(tmp_path: Path) -> None:
    root = _tum_copy(tmp_path, camera=False)
    out = tmp_path / "o.pcdc"
    cam = ("--fx", "525", "--fy", "525", "--cx", "319.5", "--cy", "239.5")
    result = _cli("encode", str(root), "-o", str(out), "--max-frames", "2", *cam)
    assert result.returncode == 0, result.stderr
    assert "depth scale  5000 units per metre (from TUM RGB-D dataset)" in result.stdout
    with pcdcodec.open(out) as rec:
        assert rec.depth_scale == 5000.0


def test_cli_bench_refuses_zero_frames() -> None:
    result = _cli("bench", str(sample_dir()), "--frames", "0", "--no-rd")
    assert result.returncode == 1
    assert "--frames must be at least 1, got 0" in result.stderr
    assert "Traceback" not in result.stderr


# -- crash loss at the defaults ---------------------------------------------------------------


def _held_back(spec: Any, frames: int = 20) -> int:
    """The most frames the codec's encoder held back at once while frames went in."""
    codec = pcdcodec.get_codec(spec, kind="color")
    assert isinstance(codec, StreamCodec)
    encoder = codec.encoder(64, 64, 30.0)
    rng = np.random.default_rng(0)
    out = held = 0
    for i in range(frames):
        rgb = rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)
        out += len(encoder.encode(rgb, i * 33_000_000))
        held = max(held, i + 1 - out)
    assert out + len(encoder.flush()) == frames
    return held


STREAM_CODECS = [
    name
    for name in pcdcodec.list_codecs("color", available_only=True)
    if issubclass(pcdcodec.codec_class(name), PyAVCodec)
]


@pytest.mark.parametrize("name", STREAM_CODECS)
def test_default_encoders_hold_no_frame_back(name: str) -> None:
    if name == "av1":  # documented exception: low delay costs AV1 78-121 % in size
        assert _held_back("av1") > 10
        assert _held_back({"id": "av1", "low_delay": True}) == 0
        return
    assert _held_back(name) == 0


@pytest.mark.parametrize("name", ["h264", "h265", "vp9"])
def test_without_low_delay_the_lookahead_holds_frames(name: str) -> None:
    if name not in STREAM_CODECS:
        pytest.skip(f"{name} is unavailable here")
    assert _held_back({"id": name, "low_delay": False}) > 3
    assert pcdcodec.get_codec(name).get_config()["low_delay"] is True
