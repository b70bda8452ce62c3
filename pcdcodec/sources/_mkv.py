"""The Matroska (EBML) structure of a ``.mkv`` file, read from the element heads alone.

FFmpeg (through PyAV) skips a damaged cluster and stops at a cut without a word, and leaves out
the tags of a track it cannot read. These walks read the few bytes of each element's head, so
that the Azure Kinect reader can count the blocks the file holds against the packets it was
given, and read those tags itself.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "CLUSTER_ID",
    "EBML_MAGIC",
    "blocks_by_track",
    "declared_tag",
    "has_cluster",
    "list_tracks",
    "track_name",
    "walk_blocks",
]

#: the EBML header's ID, which starts every Matroska file
EBML_MAGIC = b"\x1a\x45\xdf\xa3"
CLUSTER_ID = b"\x1f\x43\xb6\x75"


def declared_tag(path: Path, name: bytes, limit: int = 1 << 20) -> bytes | None:
    """The value of the first SimpleTag ``name`` before the first cluster, read from the bytes
    (FFmpeg leaves out the tags of a track it cannot read), or ``None``."""
    with path.open("rb") as f:
        head = f.read(limit)
    end = head.find(CLUSTER_ID)
    at = head.find(name, 0, end if end >= 0 else len(head))
    if at < 0:
        return None
    i = at + len(name)
    if head[i : i + 2] != b"\x44\x87" or i + 3 > len(head):  # TagString, one-byte size
        return b""
    size = head[i + 2]
    if not size & 0x80:
        return b""
    return head[i + 3 : i + 3 + (size & 0x7F)]


#: elements that may stand at the top of a Matroska Segment
_TOP_LEVEL = {0x114D9B74, 0x1549A966, 0x1654AE6B, 0x1F43B675, 0x1C53BB6B, 0x1941A469, 0x1043A770,
              0x1254C367, 0xEC}  # fmt: skip
_SEGMENT, _CLUSTER, _SIMPLE_BLOCK, _BLOCK_GROUP, _BLOCK = (
    0x18538067, 0x1F43B675, 0xA3, 0xA0, 0xA1
)  # fmt: skip


def _element(f: Any, pos: int) -> tuple[int, int | None, int] | None:
    """``(ID, size or None when unknown, body offset)`` of the EBML element at ``pos``, or
    ``None`` when its head is cut short or is not a valid element head."""
    f.seek(pos)
    head = f.read(12)
    if not head or head[0] == 0:
        return None
    n = 8 - head[0].bit_length() + 1  # ID length from its leading zeros
    if n > 4 or len(head) < n + 1 or head[n] == 0:
        return None
    eid = int.from_bytes(head[:n], "big")
    m = 8 - head[n].bit_length() + 1
    if len(head) < n + m:
        return None
    size = int.from_bytes(head[n : n + m], "big") & ((1 << (7 * m)) - 1)
    return eid, (None if size == (1 << (7 * m)) - 1 else size), pos + n + m


#: top-level elements a Segment holds once, and the first child each other one must start with
_ONCE = {0x1549A966: "Info", 0x1654AE6B: "Tracks", 0x1941A469: "Attachments"}
_FIRST_CHILD = {0x1254C367: (0x7373, "Tags"), 0x1C53BB6B: (0xBB, "Cues")}
_TIMESTAMP = 0xE7


def _misplaced(f: Any, eid: int, body: int, size: int, seen: set[int]) -> str | None:
    """Why a top-level element other than a Cluster cannot be what its ID says (a Cluster whose
    ID was damaged into another top-level ID reads as that element, and its captures vanish),
    or ``None``."""
    if eid in _ONCE and eid in seen:
        return f"is a second {_ONCE[eid]} element"
    child = _element(f, body) if size else None
    while child is not None and child[0] in (0xBF, 0xEC) and child[1] is not None:
        # CRC-32 and Void elements may come first in any master element
        nxt = child[2] + child[1]
        child = _element(f, nxt) if nxt < body + size else None
    if eid in _FIRST_CHILD and size and (child is None or child[0] != _FIRST_CHILD[eid][0]):
        return f"is a {_FIRST_CHILD[eid][1]} element that does not hold what one holds"
    if eid == 0xEC and child is not None and child[0] == _TIMESTAMP:
        return "is a Void element that holds a cluster's timestamp"
    return None


def _track(f: Any, body: int) -> int:
    """The track number a Block or SimpleBlock at ``body`` belongs to (0 when unreadable)."""
    f.seek(body)
    head: bytes = f.read(8)
    if not head or head[0] == 0:
        return 0
    n = 8 - head[0].bit_length() + 1
    if len(head) < n:
        return 0
    return int.from_bytes(head[:n], "big") & ((1 << (7 * n)) - 1)


def walk_blocks(path: Path) -> tuple[int, str | None]:
    """The number of blocks the Segment's clusters hold, and the first structural problem met
    (an element cut short or overrunning its parent, a stray element), walked from the element
    heads alone (bodies are skipped, so this reads a few bytes per block)."""
    tracks, problem = blocks_by_track(path)
    return sum(tracks.values()), problem


def blocks_by_track(path: Path) -> tuple[dict[int, int], str | None]:
    """The blocks the Segment's clusters hold per track number, and the first structural
    problem met (see :func:`walk_blocks`): a track's message count, from the element heads and
    each block's first bytes."""
    tracks: dict[int, int] = {}

    def count(body: int) -> None:
        number = _track(f, body)
        tracks[number] = tracks.get(number, 0) + 1

    file_size = path.stat().st_size
    with path.open("rb") as f:
        first = _element(f, 0)
        second = None if first is None or first[1] is None else _element(f, first[2] + first[1])
        if second is None or second[0] != _SEGMENT:
            return tracks, "no Segment after the EBML header"
        end = file_size if second[1] is None else second[2] + second[1]
        problem = None
        if end > file_size:
            problem = f"it is cut short: its Segment declares {end} bytes, the file has {file_size}"
            end = file_size
        seen: set[int] = set()
        pos = second[2]
        while pos < end:
            el = _element(f, pos)
            if el is None or el[0] not in _TOP_LEVEL:
                what = "a cut or damaged element" if el is None else f"element 0x{el[0]:X}"
                return tracks, problem or f"byte {pos} holds {what}, not a top-level element"
            eid, size, body = el
            stop = end if size is None else body + size
            if stop > end:
                return tracks, problem or f"the element at byte {pos} runs past the Segment"
            if eid != _CLUSTER:
                if size is None:
                    return tracks, problem or f"the element at byte {pos} has no size"
                odd = _misplaced(f, eid, body, size, seen)
                if odd:
                    return tracks, problem or f"the element at byte {pos} {odd}"
                seen.add(eid)
                pos = stop
                continue
            p = body
            while p < stop:
                child = _element(f, p)
                if child is None:
                    return tracks, problem or f"byte {p} in a cluster holds no element"
                cid, csize, cbody = child
                if size is None and cid in _TOP_LEVEL:
                    break  # a cluster of unknown size ends where the next top-level one starts
                if csize is None or cbody + csize > stop:
                    return tracks, problem or f"the element at byte {p} runs past its cluster"
                if cid == _SIMPLE_BLOCK:
                    count(cbody)
                elif cid == _BLOCK_GROUP:
                    q = cbody
                    while q < cbody + csize:
                        inner = _element(f, q)
                        if inner is None or inner[1] is None:
                            break
                        if inner[0] == _BLOCK:
                            count(inner[2])
                        q = inner[2] + inner[1]
                p = cbody + csize
            pos = p if size is None else stop
    return tracks, problem


def has_cluster(path: Path, limit: int = 1 << 24) -> bool:
    """Whether a Matroska Cluster element starts within the first ``limit`` bytes."""
    with path.open("rb") as f:
        return CLUSTER_ID in f.read(limit)


def track_name(stream: Any) -> str:
    """The name a track is listed by: its title (``COLOR``, ``DEPTH``, ``IR``, ``IMU``), else
    ``track N``."""
    return str(dict(stream.metadata).get("title") or f"track {stream.index + 1}")


def list_tracks(streams: Any) -> list[tuple[int | None, str, str]]:
    """``(track number, name, kind)`` of every track of a file PyAV opened, and ``(None,
    file name, "attachment")`` of every attachment, in name order. A track's number is its
    place among the tracks (PyAV's stream index + 1), as k4arecorder numbers them."""
    out: list[tuple[int | None, str, str]] = []
    for s in streams:
        if s.type == "attachment":
            out.append((None, str(dict(s.metadata).get("filename", "")), "attachment"))
            continue
        ctx = s.codec_context
        codec = str(getattr(ctx, "codec_tag", "") or getattr(ctx, "name", "") or "")
        out.append((s.index + 1, track_name(s), f"{s.type} {codec}".strip()))
    return sorted(out, key=lambda t: t[1])


def packets(container: Any, streams: Any, where: str) -> Iterator[Any]:
    """The non-empty packets PyAV demuxes of ``streams`` (every track for ``None``), in file
    order; a damaged file is a :class:`~pcdcodec.DecodeError` naming ``where``."""
    import av

    from ..errors import DecodeError

    demuxed = container.demux() if streams is None else container.demux(streams)
    while True:
        try:
            packet = next(demuxed)
        except StopIteration:
            return
        except (av.error.FFmpegError, OSError) as exc:
            raise DecodeError(f"{where}: the file is damaged: {exc}") from exc
        if packet.size:
            yield packet
