"""OpenCV's cv2.VideoWriter path (the paper's) against the PyAV packet codecs, on the same frames.

Prints a Markdown table: bytes per frame, mean RGB PSNR (inf when bit-exact), and the median
encode and decode time per frame over a few rounds. OpenCV bytes are the whole file (container
included); PyAV bytes are the packets plus the decoder's extradata. OpenCV times include opening
and finishing the file (the writer reads the header back to check the frame count).

    .venv/bin/python benchmarks/opencv_vs_pyav.py [--rounds N] [--frames FOLDER]

``FOLDER`` holds the RGB images (default: the bundled TUM sample, 15 frames of 640×480).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec.color import StreamCodec, decode_packets, encode_frames
from pcdcodec.color.opencv import FOURCCS, OpenCVVideo
from pcdcodec.metrics import psnr

SAMPLE_RGB = Path(pcdcodec.__file__).resolve().parent / "data" / "tum_fr1_rpy" / "rgb"


def mean_psnr(decoded: list[np.ndarray[Any, Any]], frames: list[np.ndarray[Any, Any]]) -> float:
    if len(decoded) != len(frames):
        raise RuntimeError(f"{len(decoded)} frames decoded of {len(frames)}")
    return float(np.mean([psnr(d, f) for d, f in zip(decoded, frames, strict=True)]))


def median_ms(fn: Callable[[], Any], rounds: int, frames: int) -> float:
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1000 / frames


def load_frames(folder: Path) -> list[np.ndarray[Any, Any]]:
    import imagecodecs

    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".png", ".jpg"))
    return [np.ascontiguousarray(imagecodecs.imread(str(p))[..., :3]) for p in paths]


def measure_opencv(
    fourcc: str, frames: list[np.ndarray[Any, Any]], rounds: int, folder: Path
) -> dict[str, Any]:
    codec = OpenCVVideo(fourcc=fourcc)
    h, w = frames[0].shape[:2]
    path = folder / f"color{codec.suffix}"

    def encode() -> None:
        with codec.writer(path, w, h, 30.0, overwrite=True) as writer:
            for frame in frames:
                writer.write(frame)

    def decode() -> list[np.ndarray[Any, Any]]:
        with codec.reader(path) as reader:
            return list(reader)

    encode()
    return {
        "bytes": path.stat().st_size / len(frames),
        "psnr": mean_psnr(decode(), frames),
        "encode": median_ms(encode, rounds, len(frames)),
        "decode": median_ms(decode, rounds, len(frames)),
    }


def measure_pyav(name: str, frames: list[np.ndarray[Any, Any]], rounds: int) -> dict[str, Any]:
    codec = pcdcodec.get_codec(name)
    assert isinstance(codec, StreamCodec)
    h, w = frames[0].shape[:2]
    packets, extradata = encode_frames(codec, frames)

    def decode() -> list[np.ndarray[Any, Any]]:
        return [f.rgb for f in decode_packets(codec, packets, w, h, extradata)]

    size = sum(len(p.data) for p in packets) + len(extradata or b"")
    return {
        "bytes": size / len(frames),
        "psnr": mean_psnr(decode(), frames),
        "encode": median_ms(lambda: encode_frames(codec, frames), rounds, len(frames)),
        "decode": median_ms(decode, rounds, len(frames)),
    }


def row(backend: str, result: dict[str, Any] | None, why: str = "") -> str:
    if result is None:
        return f"| {backend} | — | — | — | — ({why}) |"
    quality = "inf" if result["psnr"] == float("inf") else f"{result['psnr']:.2f}"
    return (
        f"| {backend} | {result['bytes']:,.0f} | {quality} | {result['encode']:.2f} "
        f"| {result['decode']:.2f} |"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="timed rounds (median is shown)")
    parser.add_argument("--frames", type=Path, default=SAMPLE_RGB, help="folder of RGB images")
    args = parser.parse_args(argv)

    frames = load_frames(args.frames)
    h, w = frames[0].shape[:2]
    print(f"{len(frames)} frames of {w}x{h} from {args.frames}; median of {args.rounds} rounds\n")
    print("| codec | bytes/frame | PSNR dB | encode ms/frame | decode ms/frame |")
    print("|---|---:|---:|---:|---:|")
    pyav_results: dict[str, dict[str, Any]] = {}  # mp4v and XVID share PyAV's mpeg4
    with tempfile.TemporaryDirectory(prefix="pcdcodec-bench-") as tmp:
        for fourcc, (suffix, pyav_name) in FOURCCS.items():
            label = f"OpenCV `{fourcc}` ({suffix})"
            if OpenCVVideo.fourcc_available(fourcc):
                print(row(label, measure_opencv(fourcc, frames, args.rounds, Path(tmp))))
            else:
                print(row(label, None, "does not open in this OpenCV build"))
            label = f"PyAV `{pyav_name}`"
            cls = pcdcodec.codec_class(pyav_name)
            if cls.is_available():
                if pyav_name not in pyav_results:
                    pyav_results[pyav_name] = measure_pyav(pyav_name, frames, args.rounds)
                print(row(label, pyav_results[pyav_name]))
            else:
                print(row(label, None, str(cls.unavailable_reason())))


if __name__ == "__main__":
    main()
