"""Where the bytes of a ``.pcdc`` recording go, per frame.

Run: ``python scripts/recording_bytes.py [--frames 60] [--sets sample,tum_fr1_rpy,...]
[--json OUT] [FILE.pcdc ...]``.

For each set present (the bundled sample and the dense sequences of ``../shared/data``) it
writes the first ``--frames`` frames with the default codecs (poses where the set has them),
then walks every record of the file and puts each byte in one category: the color packets,
the CDR wrapper around them, the encoded depth frames (body and ``PCDF`` header apart), the
pose and digest payloads, the headers of the message records, the chunk headers, the message
indexes, the metadata records, the summary (chunk indexes and the rest) and the file's own
framing. Files named on the command line are measured as they are. The overhead is what is not
color packet or encoded depth frame; the whole-stream ratio is the size of a PointCloud2 XYZRGB
of the valid points (32 bytes per point) over the file's size.
"""

from __future__ import annotations

import argparse
import json
import struct
import sys
import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import load_folder, load_sample
from pcdcodec.recording import _index as fmt
from pcdcodec.ros.foxglove import CompressedVideo

#: Bytes per point of a PointCloud2 XYZRGB (float32 x, y, z, packed RGB, padding).
PC2_BYTES = 32
_MAGIC = b"\x89MCAP0\r\n"
_RECORD = 9  # opcode and length
_MESSAGE_HEAD = 2 + 4 + 8 + 8  # channel, sequence, log time, publish time
_SUMMARY_NAMES = {
    0x03: "summary: schemas",
    0x04: "summary: channels",
    0x08: "summary: chunk indexes",
    0x0A: "summary: other",
    0x0B: "summary: other",
    0x0D: "summary: other",
    0x0E: "summary: other",
}
#: The categories that are the streams themselves; everything else is overhead.
PAYLOAD = ("color packets", "depth frame bodies", "depth frame headers")


def _records(data: bytes, pos: int, end: int) -> Any:
    while pos < end:
        opcode = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        yield pos, opcode, data[pos + _RECORD : pos + _RECORD + length]
        pos += _RECORD + length


def _message(content: bytes, topics: dict[int, str], out: Counter[str]) -> None:
    """Count one message record's content by what it carries."""
    (channel,) = struct.unpack_from("<H", content)
    data = content[_MESSAGE_HEAD:]
    out["message record headers"] += _RECORD + _MESSAGE_HEAD
    topic = topics.get(channel, "?")
    if topic == fmt.TOPIC_COLOR:
        try:
            packet = len(CompressedVideo.decode(data).data)
        except Exception:  # a raw packet (codecs without a standard schema)
            packet = len(data)
        out["color packets"] += packet
        out["color CDR wrapper"] += len(data) - packet
    elif topic == fmt.TOPIC_DEPTH:
        head = 28 + data[7] if len(data) > 8 else len(data)
        out["depth frame headers"] += head
        out["depth frame bodies"] += len(data) - head
    elif topic in (fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX):
        out["pose payloads"] += len(data)
    elif topic == fmt.TOPIC_FRAME_DIGEST:
        out["frame digest payloads"] += len(data)
    else:
        out["other payloads (calibration, markers)"] += len(data)


def breakdown(path: Path) -> dict[str, Any]:
    """Bytes of the recording at ``path`` by category, and its frame count."""
    data = path.read_bytes()
    out: Counter[str] = Counter()
    topics: dict[int, str] = {}
    out["file framing (magic, header, footer)"] += 2 * len(_MAGIC)
    footer = len(data) - len(_MAGIC) - _RECORD - 20
    (summary_start,) = struct.unpack_from("<Q", data, footer + _RECORD)
    end = summary_start if summary_start else footer
    for _pos, opcode, content in _records(data, 8, end):
        if opcode == 0x06:  # chunk
            (clen,) = struct.unpack_from("<I", content, 28)
            compression = content[32 : 32 + clen].decode()
            head = 32 + clen + 8
            out["chunk headers"] += _RECORD + head
            inner = content[head:]
            if compression:
                out["compressed chunk contents"] += len(inner)
                continue
            for _p, op, rec in _records(inner, 0, len(inner)):
                if op == 0x05:
                    _message(rec, topics, out)
                elif op == 0x04:
                    (cid,) = struct.unpack_from("<H", rec)
                    (tlen,) = struct.unpack_from("<I", rec, 4)
                    topics[cid] = rec[8 : 8 + tlen].decode()
                    out["schemas and channels in chunks"] += _RECORD + len(rec)
                else:
                    out["schemas and channels in chunks"] += _RECORD + len(rec)
        elif opcode == 0x07:
            out["message indexes"] += _RECORD + len(content)
        elif opcode == 0x0C:
            out["metadata records"] += _RECORD + len(content)
        elif opcode == 0x05:
            _message(content, topics, out)
        elif opcode in (0x01, 0x0F):
            out["file framing (magic, header, footer)"] += _RECORD + len(content)
        else:
            out["schemas and channels in chunks"] += _RECORD + len(content)
    if summary_start:
        for _pos, opcode, content in _records(data, end, footer):
            name = _SUMMARY_NAMES.get(opcode, "file framing (magic, header, footer)")
            out[name] += _RECORD + len(content)
    out["file framing (magic, header, footer)"] += _RECORD + 20
    assert sum(out.values()) == len(data), (sum(out.values()), len(data))
    with pcdcodec.open(path) as rec:
        frames = len(rec)
    return {"bytes": dict(out), "size": len(data), "frames": frames}


def write_set(name: str, frames: int, path: Path) -> float:
    """Write the first ``frames`` frames of set ``name`` with the default codecs; the mean
    number of valid depth points per frame."""
    if name == "sample":
        seq = load_sample(max_frames=frames)
    else:
        spec = SEQUENCES[name]
        seq = load_folder(spec.root, max_frames=frames, **spec.reader_options())
    with pcdcodec.open(
        path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, overwrite=True
    ) as writer:
        writer.write_frames(seq)
    return float(np.mean([np.count_nonzero(f.depth) for f in seq]))


def report(name: str, result: dict[str, Any], valid: float | None) -> dict[str, Any]:
    """Print the table of one recording; per-frame figures added to ``result``."""
    n = max(result["frames"], 1)
    parts = result["bytes"]
    overhead = sum(v for k, v in parts.items() if k not in PAYLOAD)
    result["overhead_per_frame"] = overhead / n
    print(f"\n### {name}: {result['frames']} frames, {result['size']:,} bytes")
    print("| category | bytes | per frame |")
    print("|---|---:|---:|")
    for key, value in sorted(parts.items(), key=lambda kv: -kv[1]):
        mark = "" if key in PAYLOAD else " (overhead)"
        print(f"| {key}{mark} | {value:,} | {value / n:,.1f} |")
    per_frame = overhead / n
    print(f"| **overhead** | {overhead:,} | **{per_frame:,.1f}** ({per_frame / 1024:.2f} KiB) |")
    if valid is not None:
        pc2 = valid * PC2_BYTES * n
        result["ratio"] = pc2 / result["size"]
        result["ratio_without_overhead"] = pc2 / (result["size"] - overhead)
        print(
            f"whole stream vs PointCloud2 ({valid:,.0f} valid points/frame): "
            f"{result['ratio']:.1f}x (with no overhead at all: "
            f"{result['ratio_without_overhead']:.1f}x)"
        )
    return result


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="*", type=Path, help="recordings to measure as they are")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--sets", help="comma-separated set names (default: every one present)")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    results: dict[str, Any] = {}
    for path in args.files:
        results[str(path)] = report(str(path), breakdown(path), None)
    if not args.files or args.sets:
        present = [n for n, s in SEQUENCES.items() if s.present]
        names = args.sets.split(",") if args.sets else present
        with tempfile.TemporaryDirectory() as tmp:
            for name in names:
                path = Path(tmp) / f"{name}.pcdc"
                valid = write_set(name, args.frames, path)
                results[name] = report(name, breakdown(path), valid)
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main(sys.argv[1:])
