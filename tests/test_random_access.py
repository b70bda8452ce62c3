"""Random access (``rec[i]``): exactly the frames reading in order gives, in any order (random,
backwards, repeated, across keyframes), on threads, from a reader shared by threads; decoding
only from the keyframe before a frame, and converting to RGB only the frame asked for.
"""

from __future__ import annotations

import itertools
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.color.base import DecodedFrame, DecodedPicture
from pcdcodec.color.ffmpeg import FFmpegDecoder
from pcdcodec.recording._readahead import KEEP_PICTURES, ColorStream

W, H = 64, 48
CAMERA = pcdcodec.CameraIntrinsics(W, H, 52.5, 52.5, 31.5, 23.5)
N = 60
GOP = 7


def record(path: Path, color: Any) -> Path:
    yy, xx = np.mgrid[0:H, 0:W]
    texture = np.random.default_rng(5).integers(0, 12, (H, W + N, 3))
    with pcdcodec.open(path, "w", intrinsics=CAMERA, depth_scale=1000.0, color=color) as w:
        for i in range(N):
            rgb = np.stack(
                [(xx * 4 + i * 3) % 256, (yy * 5 + i * 2) % 256, ((xx + yy) * 3 + i) % 256], -1
            )
            rgb = (rgb + texture[:, i : i + W]).astype(np.uint8)  # moving texture to code
            d = (1000 + xx * 7 + yy * 11 + i * 13).astype(np.uint16)
            d[(xx + i) % 9 == 0] = 0
            w.write(rgb, d, 1_000_000_000 + i * 33_333_333)
    return path


def available(name: str) -> bool:
    return pcdcodec.get_codec(name).unavailable_reason() is None


CODECS: dict[str, dict[str, Any]] = {
    "h264": {"id": "h264", "gop": GOP},
    "h264-bframes": {"id": "h264", "gop": GOP, "bframes": 2},
    "h265": {"id": "h265", "gop": GOP},
    "vp9": {"id": "vp9", "gop": GOP},
    "av1": {"id": "av1", "gop": GOP},
}


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("random-access")
    return {
        name: record(root / f"{name}.pcdc", config)
        for name, config in CODECS.items()
        if available(config["id"])
    }


_in_order: dict[str, list[tuple[bytes, bytes]]] = {}


def in_order(path: Path) -> list[tuple[bytes, bytes]]:
    """Color and depth of every frame, read in order on one thread."""
    if str(path) not in _in_order:
        with pcdcodec.open(path) as rec:
            _in_order[str(path)] = [(f.color.tobytes(), f.depth.tobytes()) for f in rec]  # type: ignore[union-attr]
    return _in_order[str(path)]


def orders() -> dict[str, list[int]]:
    rng = np.random.default_rng(11)
    return {
        "random": rng.permutation(N).tolist(),
        "random-again": rng.permutation(N).tolist(),
        "backwards": list(range(N - 1, -1, -1)),
        "repeated": [3, 3, 20, 3, 20, 20, 59, 59, 0, 0],
        "across-keyframes": [6, 7, 8, 13, 14, 6, 15, 5, 21, 20, 22, 28, 27],
        "with-negative": [-1, -N, -8, 7, -1],
    }


@pytest.mark.parametrize("threads", [None, 2])
@pytest.mark.parametrize("order", list(orders()))
@pytest.mark.parametrize("codec", list(CODECS))
def test_random_access_gives_the_frames_in_order_exactly(
    recordings: dict[str, Path], codec: str, order: str, threads: int | None
) -> None:
    if codec not in recordings:
        pytest.skip(f"{codec} is not available here")
    path = recordings[codec]
    expected = in_order(path)
    with pcdcodec.open(path, threads=threads) as rec:
        assert len(rec) == N
        for i in orders()[order]:
            frame = rec[i]
            assert frame.index == i % N
            assert frame.color is not None
            assert frame.color.tobytes() == expected[i][0], f"color of frame {i}"
            assert frame.depth.tobytes() == expected[i][1], f"depth of frame {i}"


def test_random_access_between_reading_in_order(recordings: dict[str, Path]) -> None:
    """Iterating (on threads or not) and ``rec[i]`` on one reader do not disturb each other."""
    path = recordings["h264"]
    expected = in_order(path)
    for threads in (None, 2):
        with pcdcodec.open(path, threads=threads) as rec:
            it = iter(rec)
            for n, frame in enumerate(it):
                assert frame.color is not None
                assert frame.color.tobytes() == expected[n][0]
                back = rec[(n * 17) % N]
                assert back.color is not None
                assert back.color.tobytes() == expected[(n * 17) % N][0]
                if n == 30:
                    break
            assert [f.depth.tobytes() for f in it] == [e[1] for e in expected[31:]]


def test_frames_returned_are_new_arrays(recordings: dict[str, Path]) -> None:
    """A kept picture is converted afresh each time: changing one frame's color changes no other."""
    with pcdcodec.open(recordings["h264"]) as rec:
        first = rec[10]
        assert first.color is not None
        first.color[:] = 0
        again = rec[10]
        assert again.color is not None
        assert again.color.tobytes() == in_order(recordings["h264"])[10][0]


def test_a_reader_shared_by_threads(recordings: dict[str, Path]) -> None:
    path = recordings["h264"]
    expected = in_order(path)
    errors: list[str] = []
    with pcdcodec.open(path) as rec:

        def read(seed: int) -> None:
            for i in np.random.default_rng(seed).integers(0, N, 40).tolist():
                frame = rec[i]
                assert frame.color is not None
                if frame.color.tobytes() != expected[i][0]:
                    errors.append(f"color of frame {i} (thread {seed})")
                if frame.depth.tobytes() != expected[i][1]:
                    errors.append(f"depth of frame {i} (thread {seed})")

        threads = [threading.Thread(target=read, args=(seed,)) for seed in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert errors == []


class Counting:
    """Counts the color packets a reader decodes and the pictures it converts to RGB."""

    def __init__(self, rec: Any, monkeypatch: pytest.MonkeyPatch) -> None:
        self.packets: list[int] = []
        self.converted = 0
        packet = rec._packet

        def counting_packet(j: int) -> Any:
            self.packets.append(j)
            return packet(j)

        rgb = FFmpegDecoder._rgb

        def counting_rgb(decoder: Any, frame: Any) -> Any:
            self.converted += 1
            return rgb(decoder, frame)

        monkeypatch.setattr(rec, "_packet", counting_packet)
        monkeypatch.setattr(FFmpegDecoder, "_rgb", counting_rgb)

    def clear(self) -> None:
        self.packets.clear()
        self.converted = 0


def test_seeking_decodes_from_the_keyframe_and_converts_one_picture(
    recordings: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    with pcdcodec.open(recordings["h264"]) as rec:
        keys = rec.keyframes
        assert keys[0] == 0
        assert max(np.diff(keys)) <= GOP
        # A group of pictures of at least 4 frames after the first.
        k, next_key = next((a, b) for a, b in itertools.pairwise(keys[1:]) if b - a >= 4)
        target = next_key - 2
        count = Counting(rec, monkeypatch)
        rec[target]
        assert count.packets == list(range(k, target + 1))
        assert count.converted == 1  # the frames before it were decoded, not converted
        count.clear()
        # Backwards and again within the group of pictures: converted, not decoded again.
        for i in range(target, k - 1, -1):
            rec[i]
        rec[target]
        assert count.packets == []
        assert count.converted == target - k + 2
        count.clear()
        # Forward from where the decoder stands: no seek.
        rec[target + 1]
        assert count.packets == [target + 1]
        count.clear()
        # Another group: decoded from its keyframe; its pictures replace those kept.
        rec[2]
        assert count.packets == [0, 1, 2]
        count.clear()
        rec[k + 1]
        assert count.packets == [k, k + 1]


@pytest.mark.parametrize("codec", ["h264", "h264-bframes", "av1"])
def test_reading_in_order_decodes_and_converts_each_picture_once(
    recordings: dict[str, Path], monkeypatch: pytest.MonkeyPatch, codec: str
) -> None:
    """Also where frames come out of the decoder later than their packets go in (B-frames)."""
    if codec not in recordings:
        pytest.skip(f"{codec} is not available here")
    with pcdcodec.open(recordings[codec]) as rec:
        count = Counting(rec, monkeypatch)
        for _ in rec:
            pass
        assert count.converted == N
        assert sorted(count.packets) == list(range(N))


def test_pictures_kept_stay_within_their_budget(recordings: dict[str, Path]) -> None:
    path = recordings["h264-bframes"]
    expected = in_order(path)
    with pcdcodec.open(path) as rec:
        picture_bytes = W * H * 3 // 2
        for keep in (1, 2 * picture_bytes, KEEP_PICTURES):
            stream = ColorStream(rec, rec.color_shape, keep=keep)
            for i in [*range(N - 1, -1, -1), *np.random.default_rng(keep).permutation(N)]:
                color = stream.color(int(i))
                assert color is not None
                assert color.tobytes() == expected[int(i)][0]
                assert sum(p.nbytes for p in stream._pictures.values()) <= keep
        # Reading in order (keep 0) holds only the pictures decoded ahead of the one shown.
        stream = ColorStream(rec, rec.color_shape)
        for i in range(N):
            stream.color(i)
            assert all(t > rec.timestamps[i] for t in stream._pictures)


def test_decoded_picture_of_a_frame_in_rgb() -> None:
    """A decoder that cannot put the conversion off still gives pictures, each a new array."""
    rgb = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    picture = DecodedPicture.of(DecodedFrame(rgb, 7))
    assert picture.timestamp == 7
    assert picture.nbytes == rgb.nbytes
    a, b = picture.rgb(), picture.rgb()
    assert a.tobytes() == b.tobytes() == rgb.tobytes()
    assert a is not rgb
    assert b is not a
