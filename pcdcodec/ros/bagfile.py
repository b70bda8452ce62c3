"""Bag files on disk: telling a ROS 1 bag, a ROS 2 bag (folder, sqlite3 or mcap file) from other
files, and opening one with rosbags, whatever its name ends in.

The bag's own damage checks come with the reader: every file is read through
:func:`~pcdcodec.ros.bagindex.bounded_path` and every ROS 1 index through
:func:`~pcdcodec.ros.bagindex.check_ros1_index`, and the bag library's errors come back as
:class:`~pcdcodec.DecodeError` (:func:`bag_error`).
"""

from __future__ import annotations

import struct
import tempfile
from pathlib import Path
from typing import Any

from ..errors import DecodeError, InputError, PcdcodecError
from . import bagindex

__all__ = [
    "MCAP_MAGIC",
    "ROS1_MAGIC",
    "SQLITE_MAGIC",
    "bag_error",
    "bag_kind",
    "is_bag_folder",
    "is_bag_head",
    "mcap_profile",
    "open_reader",
]

ROS1_MAGIC = b"#ROSBAG V2.0\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: The recording metadata keys that say what kind of bag its input was (:func:`bag_kind`).
FORMAT_KEY, STORAGE_KEY = "bag_format", "bag_storage"


def mcap_profile(head: bytes) -> str | None:
    """The profile an MCAP file's header names (``"ros2"`` for ROS 2 bags), from the file's
    first 64 bytes, or ``None`` for a file that is not MCAP."""
    if not head.startswith(MCAP_MAGIC) or len(head) < 21 or head[8] != 0x01:
        return None
    (n,) = struct.unpack_from("<I", head, 17)
    if 21 + n > len(head):
        return None
    return head[21 : 21 + n].decode(errors="replace")


def is_bag_folder(path: Path) -> bool:
    """Whether the folder ``path`` is a ROS 2 bag (its ``metadata.yaml`` says so)."""
    meta = path / "metadata.yaml"
    try:
        return meta.is_file() and "rosbag2_bagfile_information" in meta.read_text()[:4096]
    except OSError:
        return False


def is_bag_head(head: bytes) -> bool:
    """Whether a file whose first 64 bytes are ``head`` is a ROS 1 bag or a ROS 2 ``.db3`` or
    ``.mcap`` bag (``.pcdc`` recordings are MCAP too, with pcdcodec's own profile)."""
    if head.startswith(ROS1_MAGIC) or head.startswith(SQLITE_MAGIC):
        return True
    return mcap_profile(head) == "ros2"


def bag_kind(path: Path, ros2: bool) -> dict[str, str]:
    """The metadata that notes what kind of bag ``path`` is: ``bag_format`` (``rosbag1``,
    ``rosbag2``) and, of a ROS 2 bag, ``bag_storage`` (``mcap``, ``sqlite3``) from its
    storage files' first bytes."""
    if not ros2:
        return {FORMAT_KEY: "rosbag1"}
    files = sorted(p for p in path.iterdir() if p.is_file()) if path.is_dir() else [path]
    for f in files:
        try:
            with f.open("rb") as fh:
                head = fh.read(16)
        except OSError:
            continue
        if head.startswith(MCAP_MAGIC):
            return {FORMAT_KEY: "rosbag2", STORAGE_KEY: "mcap"}
        if head.startswith(SQLITE_MAGIC):
            return {FORMAT_KEY: "rosbag2", STORAGE_KEY: "sqlite3"}
    return {FORMAT_KEY: "rosbag2"}


def bag_error(exc: Exception, path: Path) -> PcdcodecError:
    """The bag library's error ``exc`` as a :class:`~pcdcodec.DecodeError` naming the bag."""
    text = str(exc) or type(exc).__name__
    return DecodeError(f"cannot read bag {str(path)!r}: {text} (is the file complete?)")


def open_reader(path: Path) -> tuple[Any, tempfile.TemporaryDirectory[str] | None]:
    """An open rosbags ``AnyReader`` of the bag at ``path`` (ROS 2 messages read with the
    Humble typestore where the bag brings no definitions), and the temporary folder that holds
    a link to a file whose name does not end as rosbags expects (``None`` when not needed; the
    caller removes it after closing the reader).

    Raises :class:`~pcdcodec.InputError` when ``path`` does not exist and
    :class:`~pcdcodec.DecodeError` when the bag cannot be opened or its index is damaged.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if not path.exists():
        raise InputError(f"bag {str(path)!r} does not exist")
    tmp: tempfile.TemporaryDirectory[str] | None = None
    target = path
    if path.is_file():
        # rosbags picks ROS 1 or the ROS 2 storage by the file's suffix.
        try:
            with path.open("rb") as f:
                head = f.read(16)
        except OSError:
            head = b""  # rosbags says what is wrong with it
        suffix = (
            ".bag"
            if head.startswith(ROS1_MAGIC)
            else ".db3"
            if head.startswith(SQLITE_MAGIC)
            else ".mcap"
        )
        if path.suffix != suffix:
            tmp = tempfile.TemporaryDirectory(prefix="pcdcodec-bag-")
            target = Path(tmp.name) / f"bag{suffix}"
            target.symlink_to(path.resolve())
    try:
        try:
            reader = AnyReader(
                [bagindex.bounded_path(target)],
                default_typestore=get_typestore(Stores.ROS2_HUMBLE),
            )
            reader.open()
        except Exception as exc:
            raise bag_error(exc, path) from exc
        try:
            for bag in reader.readers:
                bagindex.check_ros1_index(bag, repr(str(path)))
        except BaseException:
            reader.close()
            raise
    except BaseException:
        if tmp is not None:
            tmp.cleanup()
        raise
    return reader, tmp
