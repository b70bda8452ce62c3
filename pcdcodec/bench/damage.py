"""What ``pcdcodec recover`` must give back from a recording whose bytes were flipped, worked
out from the undamaged file alone: which chunks each flipped byte falls in, and which frames,
color groups and keyframes those chunks hold. The tests and ``scripts/recover_damage.py``
compare ``recover``'s outcome with it.

A frame is lost when a chunk of its own (depth, frame digest, pose) is hit. A color group (the
packets between two frame digests) fails when one of its packets, their keyframe markers or
its digest is hit; a frame keeps its color when every group from its keyframe to its own
packet holds.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..recording.reader import Recording

__all__ = ["Layout", "expected", "flip"]

# The topics of a one-camera recording (docs/format.md).
DEPTH, COLOR, KEYFRAMES = "/camera/depth", "/camera/color", "/camera/color/keyframes"
FRAME_DIGEST = "/camera/frame_digest"
#: A frame's own messages: one of them hit, the frame is lost.
FRAME_TOPICS = (DEPTH, FRAME_DIGEST, "/camera/pose", "/camera/pose/matrix")


@dataclass
class Layout:
    """Where a one-camera recording keeps each frame's messages."""

    path: Path
    times: list[int]
    #: chunk offset -> end (the record's last byte + 1)
    extent: dict[int, int]
    #: per topic: time -> chunk offset
    at: dict[str, dict[int, int]]
    #: color packets in file order: (pts, chunk offset, group)
    packets: list[tuple[int, int, int]]
    #: the chunk offset of each frame digest, in file order
    digests: list[int]
    keyframes: set[int]
    data: bytes

    @classmethod
    def of(cls, path: Path) -> Layout:
        data = path.read_bytes()
        extent, pos = {}, 8
        while pos + 9 <= len(data) and data[pos] != 0x0F:  # up to the data section's end
            (length,) = struct.unpack_from("<Q", data, pos + 1)
            extent[pos] = pos + 9 + length
            pos += 9 + length
        with Recording(path) as rec:
            times = [int(t) for t in rec.timestamps.tolist()]
            index = rec.index
        at = {
            topic: dict(zip(index.times[topic], index.offsets[topic], strict=True))
            for topic in index.times
        }
        digests = sorted(index.offsets.get(FRAME_DIGEST, []))
        packets = [
            (pts, o, int(np.searchsorted(digests, o)))
            for pts, o in sorted(at.get(COLOR, {}).items(), key=lambda p: p[1])
        ]
        keyframes = set(index.times.get(KEYFRAMES, []))
        return cls(path, times, extent, at, packets, digests, keyframes, data)

    @property
    def frames_span(self) -> tuple[int, int]:
        """The bytes that hold the frames' chunks (not the settings, nor the seal)."""
        ends = [self.extent[o] for topic in self.at.values() for o in topic.values()]
        return min(self.at[DEPTH].values()), max(ends)


def harmless(layout: Layout, chunk: int, at: int, mask: int) -> bool:
    """Whether flipping the byte at ``at`` (by ``mask``) of the chunk record at ``chunk``
    leaves its messages whole: its start and end times and its uncompressed size are read by
    no one, and a records length made larger still reads the records there are (one made
    smaller cuts them, and fails the CRC)."""
    field = at - chunk
    if 9 <= field < 9 + 24:
        return True
    if 41 <= field < 49:  # the records' length, of a chunk with no compression name
        return not layout.data[at] & mask
    return False


def flip(layout: Layout, path: Path, at: list[int], mask: int = 0x20) -> Path:
    """Write ``layout``'s file to ``path`` with the bytes at offsets ``at`` flipped."""
    data = bytearray(layout.data)
    for offset in at:
        data[offset] ^= mask
    path.write_bytes(bytes(data))
    return path


def expected(layout: Layout, flips: list[int], mask: int = 0x20) -> tuple[set[int], set[int]]:
    """(times of the frames that must be left out, times of those kept without color), of
    ``layout``'s file with the bytes at ``flips`` flipped by ``mask`` (:func:`flip`)."""

    def hit(offset: int | None) -> bool:
        return offset is not None and any(
            offset <= p < layout.extent[offset] and not harmless(layout, offset, p, mask)
            for p in flips
        )

    dropped = {
        t for t in layout.times if any(hit(layout.at.get(k, {}).get(t)) for k in FRAME_TOPICS)
    }
    if not layout.packets:
        return dropped, set()
    bad_groups = {g for g, o in enumerate(layout.digests) if hit(o)}
    for pts, offset, g in layout.packets:
        if hit(offset) or hit(layout.at.get(KEYFRAMES, {}).get(pts)):
            bad_groups.add(g)
    decodes, chain = set(), False
    for pts, _, g in layout.packets:
        if g in bad_groups:
            chain = False
            continue
        chain = chain or pts in layout.keyframes
        if chain:
            decodes.add(pts)
    no_color = {t for t in layout.times if t not in dropped and t not in decodes}
    return dropped, no_color
