"""Rewriting a damaged or unfinished ``.pcdc`` file into a clean, indexed one."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import DecodeError, InputError
from . import _index as fmt

__all__ = ["recover"]


def recover(
    src: str | os.PathLike[str], dst: str | os.PathLike[str], *, overwrite: bool = False
) -> int:
    """Copy every complete message of ``src`` into a new, indexed recording ``dst``.

    Use it on a file whose writer was killed (no summary) or whose tail is cut or damaged:
    everything up to the first damaged record is kept. Returns the number of frames of the
    new file. ``src`` itself is never changed. Raises :class:`~pcdcodec.DecodeError` when
    ``src`` is not a pcdcodec recording and :class:`~pcdcodec.InputError` when ``dst`` exists
    and ``overwrite`` is false, or is the same file as ``src``.
    """
    from mcap.writer import CompressionType, Writer

    from .reader import Recording

    src_path, dst_path = Path(src), Path(dst)
    if not src_path.is_file():
        raise InputError(f"recording {str(src_path)!r} does not exist")
    if dst_path.exists() and dst_path.resolve() == src_path.resolve():
        raise InputError("recover writes a new file: the destination must differ from the source")
    if dst_path.exists() and not overwrite:
        raise InputError(f"{str(dst_path)!r} already exists; pass overwrite=True to replace it")
    with src_path.open("rb") as f:
        if f.read(8) != fmt.MAGIC:
            raise DecodeError(f"{str(src_path)!r} is not a pcdcodec recording (not an MCAP file)")
        index = fmt.scan(f)
        if index.profile != fmt.PROFILE or fmt.METADATA_NAME not in index.metadata:
            raise DecodeError(f"{str(src_path)!r} is not a pcdcodec recording")
        tmp = dst_path.with_name(f".{dst_path.name}.partial-{os.getpid()}")
        with tmp.open("wb") as out:
            writer = Writer(out, chunk_size=0, compression=CompressionType.NONE)
            writer.start(profile=fmt.PROFILE, library="pcdcodec recover")
            for name, data in index.metadata.items():
                writer.add_metadata(name, data)
            schema_ids = {
                sid: writer.register_schema(name, encoding, data)
                for sid, (name, encoding, data) in index.schemas.items()
            }
            channel_ids = {
                cid: writer.register_channel(
                    ch.topic, ch.encoding, schema_ids.get(_schema_of(index, cid), 0), ch.metadata
                )
                for cid, ch in index.channels.items()
            }
            offsets = sorted({o for topic in index.offsets.values() for o in topic})
            for offset in offsets:
                for m in fmt.read_chunk_messages(f, offset, what="recover"):
                    if m.channel_id in channel_ids:
                        writer.add_message(
                            channel_ids[m.channel_id],
                            m.log_time,
                            m.data,
                            m.publish_time,
                            m.sequence,
                        )
            writer.finish()  # type: ignore[no-untyped-call]
    os.replace(tmp, dst_path)
    with Recording(dst_path) as rec:
        return len(rec)


def _schema_of(index: fmt.FileIndex, channel_id: int) -> int:
    return index.channel_schema.get(channel_id, 0)
