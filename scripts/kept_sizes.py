"""What each topic of a bag costs: as it came (raw), under MCAP's zstd chunks, and in a ``.pcdc``
with its kept images and clouds packed (``docs/bags.md``), and the whole bag under MCAP zstd
(default level, 1 MiB chunks, as ``mcap convert`` and ``ros2 bag record`` write it) against the
``.pcdc``.

Run: ``python scripts/kept_sizes.py BAG [-o OUT.pcdc] [--kept-images raw]``. A robot bag to run it
on: ``python scripts/make_robot_bag.py --set realsense --kind ros1 --seconds 2 -o rs.bag``.
Prints a table (bytes per topic) and the ratios; zstd per topic is each topic's messages alone
in 1 MiB chunks, so the per-topic figures add up to a little more than the whole bag's.
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec

CHUNK = 1 << 20


def _zstd_chunks(messages: list[bytes]) -> int:
    """Bytes of ``messages`` in zstd chunks of about 1 MiB (the default level)."""
    import zstandard

    comp = zstandard.ZstdCompressor()
    total, chunk = 0, bytearray()
    for m in messages:
        chunk += m
        if len(chunk) >= CHUNK:
            total += len(comp.compress(bytes(chunk)))
            chunk.clear()
    return total + (len(comp.compress(bytes(chunk))) if chunk else 0)


def mcap_zstd(bag: Path, out: Path) -> tuple[int, dict[str, list[bytes]]]:
    """Write ``bag`` to ``out`` as MCAP with zstd chunks; its size and the messages by topic."""
    from mcap.writer import CompressionType, Writer
    from rosbags.highlevel import AnyReader

    by_topic: dict[str, list[bytes]] = collections.defaultdict(list)
    with AnyReader([bag]) as reader, open(out, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start("ros1" if not reader.is2 else "ros2", "kept_sizes")
        ids = {}
        for c in reader.connections:
            kind = "ros2msg" if reader.is2 else "ros1msg"
            name = c.msgtype if reader.is2 else c.msgtype.replace("/msg/", "/")
            sid = w.register_schema(name, kind, c.msgdef.data.encode())
            ids[c.id] = w.register_channel(c.topic, "cdr" if reader.is2 else "ros1", sid)
        for c, t, raw in reader.messages():
            w.add_message(ids[c.id], t, bytes(raw), t)
            by_topic[c.topic].append(bytes(raw))
        w.finish()
    return out.stat().st_size, by_topic


def pcdc_topics(path: Path) -> tuple[dict[str, list[bytes]], dict[str, int]]:
    """The stored (packed or raw) messages of each kept topic of a recording, and how many of
    them are packed."""
    from mcap.reader import make_reader

    out: dict[str, list[bytes]] = collections.defaultdict(list)
    packed: dict[str, int] = collections.defaultdict(int)
    with open(path, "rb") as f:
        for _s, channel, message in make_reader(f).iter_messages():
            if "pcdcodec.kept" in channel.metadata:
                out[channel.topic].append(bytes(message.data))
                packed[channel.topic] += channel.message_encoding.startswith("pcdcodec.")
    return out, packed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("bag", type=Path)
    parser.add_argument("-o", "--output", type=Path, default=None)
    parser.add_argument("--kept-images", choices=("lossless", "raw"), default="lossless")
    parser.add_argument("--color", default="h264")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        peer_size, by_topic = mcap_zstd(args.bag, Path(tmp) / "peer.mcap")
        out = args.output or Path(tmp) / "out.pcdc"
        start = time.perf_counter()
        summary = pcdcodec.encode(
            args.bag, out, kept_images=args.kept_images, color=args.color, overwrite=True
        )
        took = time.perf_counter() - start
        stored, packed = pcdc_topics(out)
        size = out.stat().st_size
    source = summary.source
    frame_topics = {source.get("depth_topic"): summary.bytes_depth}
    frame_topics[source.get("color_topic")] = summary.bytes_color
    width = max(map(len, by_topic))
    print(f"{'topic':<{width}}  {'raw':>12}  {'mcap zstd':>12}  {'pcdc':>12}  stored as")
    for topic, messages in sorted(by_topic.items(), key=lambda kv: -sum(map(len, kv[1]))):
        raw = sum(map(len, messages))
        if topic in frame_topics:
            ours, how = frame_topics[topic], "frames"
        elif topic in stored:
            ours = _zstd_chunks(stored[topic])
            how = f"kept, {packed[topic]} of {len(stored[topic])} packed"
        else:
            ours, how = 0, "left out"
        print(f"{topic:<{width}}  {raw:>12,}  {_zstd_chunks(messages):>12,}  {ours:>12,}  {how}")
    bag_size = sum(f.stat().st_size for f in [args.bag] if f.is_file()) or sum(
        f.stat().st_size for f in args.bag.iterdir()
    )
    print(
        f"bag {bag_size:,} B; MCAP zstd {peer_size:,} B; .pcdc {size:,} B "
        f"({args.kept_images}, color {args.color}): {bag_size / size:.1f}x the bag, "
        f"{peer_size / size:.1f}x MCAP zstd; encoded in {took:.1f} s "
        f"({bag_size / took / 1e6:.0f} MB/s of the bag)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
