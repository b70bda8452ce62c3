"""Reading in order on threads (``pcdcodec.open(path, threads=N)``): the same frames, in the same
order, bit for bit, as one frame at a time; errors at the frame they belong to; no thread left.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.recording import _index as fmt
from pcdcodec.recording._readahead import ReadAhead
from pcdcodec.recording.reader import READ_AHEAD
from pcdcodec.recording.rewrite import Message, positions, rewrite, with_data
from pcdcodec.registry import codec_class

W, H = 64, 48
CAMERA = pcdcodec.CameraIntrinsics(W, H, 52.5, 52.5, 31.5, 23.5)
N = 40


def record(path: Path, color: Any, depth: Any, poses: bool = False) -> Path:
    yy, xx = np.mgrid[0:H, 0:W]
    with pcdcodec.open(
        path, "w", intrinsics=CAMERA, depth_scale=1000.0, color=color, depth=depth
    ) as w:
        for i in range(N):
            rgb = np.stack(
                [(xx * 4 + i * 9) % 256, (yy * 5 + i * 7) % 256, ((xx + yy) * 3 + i) % 256], -1
            ).astype(np.uint8)
            d = (1000 + xx * 7 + yy * 11 + i * 13).astype(np.uint16)
            d[(xx + i) % 9 == 0] = 0
            pose = np.eye(4) if poses else None
            if pose is not None:
                pose[0, 3] = i / 10
            w.write(rgb if color else None, d, 1_000_000_000 + i * 33_333_333, pose=pose)
    return path


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("readahead")
    return {
        "default": record(root / "default.pcdc", {"id": "h264", "gop": 5}, "depthac", poses=True),
        "ffv1": record(root / "ffv1.pcdc", "ffv1", "zstd"),
        "depth-only": record(root / "depth.pcdc", None, "depthac"),
    }


def contents(frames: Any) -> list[tuple[Any, ...]]:
    return [
        (
            f.index,
            f.timestamp_ns,
            None if f.color is None else f.color.tobytes(),
            f.depth.dtype,
            f.depth.tobytes(),
            None if f.pose is None else f.pose.tobytes(),
        )
        for f in frames
    ]


def read_all(path: Path, threads: int | None) -> tuple[list[tuple[Any, ...]], str | None]:
    """The frames read in order until the first error, and that error's message."""
    out = []
    with pcdcodec.open(path, threads=threads) as rec:
        it = iter(rec)
        while True:
            try:
                frame = next(it)
            except StopIteration:
                return out, None
            except pcdcodec.DecodeError as exc:
                return out, str(exc)
            out.extend(contents([frame]))


def reader_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("pcdcodec-read")]


@pytest.mark.parametrize("name", ["default", "ffv1", "depth-only"])
@pytest.mark.parametrize("threads", [2, 3])
def test_frames_in_order_and_bit_exact(
    recordings: dict[str, Path], name: str, threads: int
) -> None:
    one, error = read_all(recordings[name], 1)
    assert error is None
    assert len(one) == N
    many, error = read_all(recordings[name], threads)
    assert error is None
    assert many == one
    with pcdcodec.open(recordings[name], threads=threads) as rec:
        assert contents(rec.play(rate=1e9, start=5)) == one[5:]
        assert contents([rec[7], rec[2]]) == [one[7], one[2]]
    assert not reader_threads()


def test_random_access_while_reading_ahead(recordings: dict[str, Path]) -> None:
    one, _ = read_all(recordings["default"], 1)
    with pcdcodec.open(recordings["default"], threads=2) as rec:
        seen = []
        for frame in rec:
            seen.extend(contents([frame]))
            j = (frame.index * 5 + 3) % N
            assert contents([rec[j]]) == [one[j]]
        assert seen == one


def test_at_most_ahead_frames_are_decoded_beyond_the_one_in_use(
    recordings: dict[str, Path],
) -> None:
    with pcdcodec.open(recordings["default"], threads=2) as rec:
        asked: list[int] = []
        inner = rec._depth_and_pose

        def counting(i: int) -> Any:
            asked.append(i)
            return inner(i)

        rec._depth_and_pose = counting  # type: ignore[method-assign]
        for frame in rec:
            assert max(asked) <= frame.index + READ_AHEAD * 2
        assert sorted(asked) == list(range(N))


def damage_depth(frame: int) -> Any:
    def edit(ms: list[Message]) -> list[Message]:
        k = positions(ms, fmt.TOPIC_DEPTH)[frame]
        data = bytearray(ms[k].data)
        data[-3] ^= 0x21
        ms[k] = with_data(ms[k], bytes(data))
        return ms

    return edit


def damage_color(packet: int) -> Any:
    def edit(ms: list[Message]) -> list[Message]:
        k = positions(ms, fmt.TOPIC_COLOR)[packet]
        data = bytearray(ms[k].data)
        data[len(data) * 2 // 3] ^= 0x10
        ms[k] = with_data(ms[k], bytes(data))
        return ms

    return edit


@pytest.mark.parametrize("name", ["default", "ffv1"])
@pytest.mark.parametrize("damage", ["depth", "color"])
def test_a_damaged_frame_fails_at_its_frame_with_the_same_error(
    recordings: dict[str, Path], tmp_path: Path, name: str, damage: str
) -> None:
    path = tmp_path / f"damaged-{damage}.pcdc"
    rewrite(recordings[name], path, damage_depth(9) if damage == "depth" else damage_color(9))
    one, error_one = read_all(path, 1)
    assert error_one is not None
    assert str(path) in error_one
    assert "frame 9 " in error_one
    assert "digest" in error_one
    assert len(one) == 9
    for threads in (2, 4):
        many, error = read_all(path, threads)
        assert many == one
        assert error == error_one
    assert not reader_threads()


def test_leaving_the_loop_stops_every_worker(recordings: dict[str, Path]) -> None:
    with pcdcodec.open(recordings["default"], threads=3) as rec:
        for frame in rec:
            assert reader_threads()  # reading ahead while the frame is in use
            if frame.index == 2:
                break
        assert not reader_threads()
        # The recording stays usable: a new loop starts from the first frame.
        assert [f.index for f in rec][:3] == [0, 1, 2]
    assert not reader_threads()


def test_close_stops_every_worker(recordings: dict[str, Path]) -> None:
    rec = pcdcodec.open(recordings["default"], threads=2)
    it = iter(rec)
    assert next(it).index == 0
    assert reader_threads()
    rec.close()
    assert not reader_threads()
    # As without threads: the closed file cannot be read further.
    with pytest.raises(pcdcodec.DecodeError, match="closed"):
        next(it)
    assert not reader_threads()


@pytest.mark.parametrize("threads", [None, 0, 1])
def test_one_frame_at_a_time_starts_no_thread(recordings: dict[str, Path], threads: Any) -> None:
    with pcdcodec.open(recordings["default"], threads=threads) as rec:
        for _ in rec:
            assert not reader_threads()


@pytest.mark.parametrize("threads", [-1, 257, 1000, 1.5, True, "2"])
def test_invalid_threads_are_refused(recordings: dict[str, Path], threads: Any) -> None:
    with pytest.raises(pcdcodec.InputError, match="threads"):
        pcdcodec.open(recordings["default"], threads=threads)


def test_threads_a_codec_does_not_take(tmp_path: Path) -> None:
    # jpegxl takes 1 … 256 threads and the video codecs 0 … 64: 0 (automatic) leaves jpegxl at
    # its default, and a count a codec does not take is the option's fault, not the file's.
    if codec_class("jpegxl").unavailable_reason() is not None:
        pytest.skip("no JPEG XL")
    path = record(tmp_path / "jxl.pcdc", "ffv1", "jpegxl")
    expected = read_all(path, None)
    assert expected[1] is None
    assert read_all(path, 0) == expected
    assert read_all(path, 3) == expected
    with pytest.raises(pcdcodec.InputError, match=r"threads=65 .*color codec ffv1") as err:
        pcdcodec.open(path, threads=65)
    assert not isinstance(err.value, pcdcodec.DecodeError)
    # Above 256 (jpegxl's own limit too) the reader refuses the count before any codec.
    with pytest.raises(pcdcodec.InputError, match=r"threads must be an int in 0\.\.256"):
        pcdcodec.open(path, threads=300)


def test_closed_from_another_thread_the_rest_comes_in_order_on_the_callers_thread() -> None:
    ahead = ReadAhead(
        0,
        20,
        color=lambda i: -i,
        rest=lambda i: i * 10,
        build=lambda i, color, rest: (i, color(), rest()),
        workers=2,
        ahead=4,
    )
    it = iter(ahead)
    got = [next(it), next(it)]
    closer = threading.Thread(target=ahead.close)
    closer.start()
    closer.join()
    assert not reader_threads()
    got.extend(it)
    assert got == [(i, -i, i * 10) for i in range(20)]
    assert not reader_threads()
