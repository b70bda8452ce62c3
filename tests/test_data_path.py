"""The data path runs one way and checks each frame once: where the writer takes it in."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
import pcdcodec.color.base
import pcdcodec.depth.base
from pcdcodec.datasets import load_sample


def _counting(module: Any, name: str, monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    real = getattr(module, name)

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return calls


@pytest.mark.parametrize("color", ["h264", "ffv1"])
def test_the_codecs_do_not_check_frames_the_writer_checked(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, color: str
) -> None:
    sample = load_sample(max_frames=4)
    depth_checks = _counting(pcdcodec.depth.base, "check_depth", monkeypatch)
    color_checks = _counting(pcdcodec.color.base, "check_color", monkeypatch)
    path = tmp_path / "once.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=sample.intrinsics, depth_scale=sample.depth_scale, color=color
    ) as rec:
        rec.write_frames(sample)
    assert depth_checks == []  # the writer's own check is the only one
    assert color_checks == []
    with pcdcodec.open(path) as rec:  # and the frames are all there, bit-exact
        assert len(rec) == len(sample)
        for got, want in zip(rec, sample, strict=True):
            assert np.array_equal(got.depth, want.depth)


def test_a_codec_used_on_its_own_still_checks_its_input() -> None:
    codec = pcdcodec.get_codec("depthac")
    with pytest.raises(pcdcodec.InputTypeError, match="uint16"):
        codec.encode(np.zeros((4, 4), np.int32))
    encoder = pcdcodec.get_codec("ffv1").encoder(8, 8, 30.0)  # type: ignore[attr-defined]
    with pytest.raises(pcdcodec.InputError, match="8x8"):
        encoder.encode(np.zeros((4, 4, 3), np.uint8), 0)


def test_a_codec_that_overrides_encode_gets_every_frame(tmp_path: Path) -> None:
    from pcdcodec.depth import Zstd

    class Counting(Zstd):
        seen = 0

        @classmethod
        def param_names(cls) -> tuple[str, ...]:
            return ("level",)

        def encode(self, depth: Any) -> bytes:
            Counting.seen += 1
            return super().encode(depth)

    sample = load_sample(max_frames=3)
    with pcdcodec.open(
        tmp_path / "own.pcdc",
        "w",
        intrinsics=sample.intrinsics,
        depth_scale=sample.depth_scale,
        depth=Counting(),
    ) as rec:
        rec.write_frames(sample)
    assert Counting.seen == len(sample)


class _OwnCameraSource(pcdcodec.Source):
    """A reader of another package: it ignores the options it is given."""

    def __init__(self, path: Path, **options: Any) -> None:
        self.path = path
        self.intrinsics = pcdcodec.CameraIntrinsics(64, 48, 10.0, 10.0, 32.0, 24.0)
        self.depth_scale = 1000.0
        self.has_color = False
        self.metadata: dict[str, Any] = {}

    def __iter__(self) -> Any:
        for i in range(3):
            yield pcdcodec.Frame(None, np.full((48, 64), 500 + i, np.uint16), i * 33_000_000)


def test_encode_keeps_the_readers_camera_unless_told_to_override(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pcdcodec.sources import base

    base.source_kinds()  # the built-in readers first, then a private copy of the registry
    monkeypatch.setattr(base, "_KINDS", dict(base._KINDS))
    base.register_source("own", lambda p: p.suffix == ".own", _OwnCameraSource, "a test reader")
    src = tmp_path / "x.own"
    src.write_bytes(b"")
    given = pcdcodec.CameraIntrinsics(64, 48, 50.0, 50.0, 32.0, 24.0)
    for camera in (given, given.to_dict()):
        out = tmp_path / "out.pcdc"
        # The input's own camera wins, and the summary says the given one was not used.
        summary = pcdcodec.encode(src, out, color=None, intrinsics=camera, overwrite=True)
        with pcdcodec.open(out) as rec:
            assert rec.intrinsics.fx == 10.0
        (note,) = summary.source["camera_notes"]
        assert "fx=50" in note
        assert "fx=10" in note
        assert "the input's is used" in note
        # override=True replaces it, whatever the reader does with its options.
        summary = pcdcodec.encode(
            src, out, color=None, intrinsics=camera, overwrite=True, override=True
        )
        with pcdcodec.open(out) as rec:
            assert rec.intrinsics == given
        assert "replaces the input's own" in summary.source["camera_notes"][0]
