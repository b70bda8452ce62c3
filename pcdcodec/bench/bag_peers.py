"""What a whole bag costs under the tools people use to keep bags small: the peers a ``.pcdc``
of a bag is measured against.

* :func:`mcap_zstd`: every message of the bag, in one MCAP file with zstd chunks. The default
  level and chunk size are those of the MCAP C++ writer that ROS 2's ``rosbag2_storage_mcap``
  records with (:data:`ZSTD_DEFAULT_LEVEL`, :data:`ROS_CHUNK_BYTES`); the strongest is zstd 19
  (:data:`ZSTD_MAX_LEVEL`), the writer's own "slowest" setting.
* :func:`ros1_lz4`: the bag as a ROS 1 bag with lz4 chunks, as ``rosbag record --lz4`` writes.
  A ROS 2 bag is converted by rosbags' own conversion rules.
* :func:`cloudini`: every ``sensor_msgs/PointCloud2`` topic through Cloudini, at its default
  1 mm, every other topic as it was, into an MCAP file laid out as Cloudini's
  ``cloudini_rosbag_converter`` writes one; :func:`cloudini_clouds` gives the clouds back.

Each returns a :class:`BagPeerResult` (sizes, ratio, seconds, peak memory). The bags are read
with rosbags (ROS 1, ROS 2 sqlite3) or the ``mcap`` reader (ROS 2 mcap, split bags file by file)
one message at a time, so memory stays bounded whatever the bag's length. Cloudini comes from
the ``pureini`` package (``pip install "pcdcodec[peers]"``), imported only when it runs.
"""

from __future__ import annotations

import contextlib
import os
import resource
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import numpy.typing as npt

from .._atomic import atomic_output
from ..errors import CodecUnavailableError, DecodeError, InputError
from ..geometry.camera import CameraIntrinsics
from ..ros import bagfile
from .bag_stream import Channel, McapOut, open_bag, ros1_schema, zstd_level

__all__ = [
    "CLOUDINI_CHUNK_BYTES",
    "CLOUDINI_SCHEMA",
    "ROS_CHUNK_BYTES",
    "ZSTD_DEFAULT_LEVEL",
    "ZSTD_MAX_LEVEL",
    "BagPeerResult",
    "CloudBack",
    "bag_bytes",
    "cloudini",
    "cloudini_clouds",
    "mcap_zstd",
    "ros1_lz4",
    "write_cloud_bag",
]

#: The zstd level of the MCAP C++ writer's default ("Default" maps to zstd 1), which ROS 2's
#: mcap storage records with unless a storage preset says otherwise.
ZSTD_DEFAULT_LEVEL = 1
#: The strongest level measured: zstd 19, the MCAP writer's "slowest" and the highest level
#: without zstd's ``--ultra`` windows (20-22 take up to 128 MiB more memory per chunk for a
#: few per cent, and neither ROS tool offers them).
ZSTD_MAX_LEVEL = 19
#: The chunk size of both ROS recorders: 768 KiB uncompressed, the MCAP C++ writer's default
#: and ROS 1 ``rosbag record``'s chunk threshold.
ROS_CHUNK_BYTES = 768 * 1024
#: The chunk size of Cloudini's rosbag converter (its MCAP chunks are zstd at the default level).
CLOUDINI_CHUNK_BYTES = 2 * 1024 * 1024

_INSTALL_HINT = 'pip install "pcdcodec[peers]"'
_CLOUD_TYPES = {"sensor_msgs/msg/PointCloud2", "sensor_msgs/PointCloud2"}
#: The message Cloudini writes in place of a PointCloud2 (package point_cloud_interfaces).
CLOUDINI_SCHEMA = "point_cloud_interfaces/msg/CompressedPointCloud2"
_CLOUDINI_MSG = """\
std_msgs/Header header
uint32 height
uint32 width
sensor_msgs/PointField[] fields
bool is_bigendian
uint32 point_step
uint32 row_step
uint8[] compressed_data
bool is_dense
string format
"""
#: Fields packing colour bits into a float; kept bit-exact (see :func:`cloudini`).
PACKED_COLOR = ("rgb", "rgba")


@dataclass(frozen=True)
class BagPeerResult:
    """One peer on one bag: ``bytes_in`` (the bag on disk, every file of a folder),
    ``bytes_out`` (what the peer wrote), the wall ``seconds`` it took, and ``peak_rss_bytes``,
    the process's resident-memory high-water mark after the run (an upper bound on the run's
    own peak; run each peer in a fresh process for the run's own)."""

    peer: str
    bag: str
    bytes_in: int
    bytes_out: int
    seconds: float
    peak_rss_bytes: int
    messages: int

    @property
    def ratio(self) -> float:
        """The bag's size over the peer's."""
        return self.bytes_in / self.bytes_out if self.bytes_out else float("inf")


def bag_bytes(path: str | os.PathLike[str]) -> int:
    """The size of a bag on disk: the file, or every file of a ROS 2 bag folder."""
    p = Path(path)
    if p.is_dir():
        return sum(f.stat().st_size for f in p.rglob("*") if f.is_file())
    return p.stat().st_size


def _peak_rss() -> int:
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak if sys.platform == "darwin" else peak * 1024)


def _run(peer: str, bag: Path, out: Path, body: Callable[[Path], int]) -> BagPeerResult:
    start = time.perf_counter()
    with atomic_output(out) as tmp:
        count = body(tmp)
    seconds = time.perf_counter() - start
    return BagPeerResult(
        peer, str(bag), bag_bytes(bag), out.stat().st_size, seconds, _peak_rss(), count
    )


def mcap_zstd(
    bag_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    level: int = ZSTD_DEFAULT_LEVEL,
    chunk_size: int = ROS_CHUNK_BYTES,
) -> BagPeerResult:
    """Every message of a ROS 1 or ROS 2 bag (sqlite3, mcap, split) rewritten into one MCAP
    file at ``out_path`` with zstd chunks at ``level``, ``chunk_size`` bytes uncompressed.

    Topics keep their schemas (name, encoding, definition), message encoding (``ros1`` or
    ``cdr``) and metadata (ROS 1: ``callerid``, ``latching``, ``md5sum``; ROS 2:
    ``offered_qos_profiles``), and every message its bytes, log time, publish time and sequence
    (a bag that keeps no publish time gets its log time). An MCAP input's metadata records and
    attachments come along. Raises :class:`~pcdcodec.InputError` for a missing bag or a level
    zstd has not, and :class:`~pcdcodec.DecodeError` for a bag that cannot be read.
    """
    bag, out = Path(bag_path), Path(out_path)

    def body(tmp: Path) -> int:
        count = 0
        with contextlib.ExitStack() as stack, zstd_level(level):
            src = open_bag(bag, stack)
            with tmp.open("wb") as f:
                mcap = McapOut(f, src.profile, chunk_size)
                for rec in src.records:
                    mcap.write(*rec)
                    count += 1
                src.extras(mcap.writer)
                mcap.writer.finish()
        return count

    return _run(f"mcap zstd {level}", bag, out, body)


# ----------------------------------------------------------------------------- ROS 1 lz4


def ros1_lz4(
    bag_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    chunk_size: int = ROS_CHUNK_BYTES,
) -> BagPeerResult:
    """The bag at ``bag_path`` as a ROS 1 bag with lz4 chunks at ``out_path``.

    A ROS 1 bag keeps every connection (topic, type, definition, MD5 sum, callerid, latching)
    and every message's bytes and time. A ROS 2 bag is converted as ``rosbags-convert`` does:
    messages re-serialized in ROS 1's wire format (``seq`` 0), definitions of the ROS 1 Noetic
    store (the bag's own for types Noetic lacks), latching from transient-local QoS.
    """
    from rosbags.interfaces import ConnectionExtRosbag1
    from rosbags.rosbag1 import Writer

    bag, out = Path(bag_path), Path(out_path)

    def body(tmp: Path) -> int:
        count = 0
        reader, tdir = bagfile.open_reader(bag)
        try:
            writer = Writer(tmp)
            writer.set_compression(Writer.CompressionFormat.LZ4)
            writer.chunk_threshold = chunk_size
            with writer:
                conns: dict[tuple[int, int], Any] = {}
                convert: dict[str, Callable[[Any], Any]] = {}
                if reader.is2:
                    from rosbags.convert.converter import create_connections_converters

                    with contextlib.redirect_stdout(sys.stderr):  # its notes on missing types
                        connmap, convert = create_connections_converters(
                            reader.connections, None, reader, writer
                        )
                    conns = {(k[0], id(k[1])): v for k, v in connmap.items()}
                else:
                    made: dict[tuple[Any, ...], Any] = {}
                    for c in reader.connections:
                        ext = c.ext
                        assert isinstance(ext, ConnectionExtRosbag1)
                        key = (c.topic, c.msgtype, c.digest, ext.callerid, ext.latching)
                        if key not in made:
                            made[key] = writer.add_connection(
                                c.topic,
                                c.msgtype,
                                msgdef=c.msgdef.data,
                                md5sum=c.digest,
                                callerid=ext.callerid,
                                latching=ext.latching,
                            )
                        conns[(c.id, id(c.owner))] = made[key]
                try:
                    for c, t, raw in reader.messages():
                        data = convert[c.msgtype](raw) if reader.is2 else raw
                        writer.write(conns[(c.id, id(c.owner))], t, bytes(data))
                        count += 1
                except Exception as exc:
                    raise bagfile.bag_error(exc, bag) from exc
        finally:
            reader.close()
            if tdir is not None:
                tdir.cleanup()
        return count

    return _run("ros1 lz4", bag, out, body)


# ----------------------------------------------------------------------------- Cloudini


def _pureini() -> ModuleType:
    try:
        import pureini
    except ImportError as exc:
        raise CodecUnavailableError(
            f"the Cloudini peer needs the pureini package: {_INSTALL_HINT}"
        ) from exc
    return pureini


def _typestore(ros2: bool) -> Any:
    """The ROS 2 Humble or ROS 1 Noetic store, with Cloudini's message registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(_CLOUDINI_MSG, CLOUDINI_SCHEMA))
    return store


class _Clouds:
    """Serializing and deserializing clouds in one channel's encoding (``cdr`` or ``ros1``)."""

    def __init__(self) -> None:
        self.stores: dict[bool, Any] = {}

    def store(self, encoding: str) -> Any:
        ros2 = encoding != "ros1"
        if ros2 not in self.stores:
            self.stores[ros2] = _typestore(ros2)
        return self.stores[ros2]

    def load(self, data: bytes, typename: str, encoding: str) -> Any:
        store = self.store(encoding)
        if encoding == "ros1":
            return store.deserialize_ros1(data, typename)
        return store.deserialize_cdr(data, typename)

    def dump(self, msg: Any, typename: str, encoding: str) -> bytes:
        store = self.store(encoding)
        if encoding == "ros1":
            return bytes(store.serialize_ros1(msg, typename))
        return bytes(store.serialize_cdr(msg, typename))


def _packed_rows(msg: Any, topic: str) -> bytes:
    """The points of a PointCloud2, rows without their padding (Cloudini codes
    ``width * point_step`` bytes a row)."""
    h, w, step, row = int(msg.height), int(msg.width), int(msg.point_step), int(msg.row_step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if row < w * step or data.size < h * row:
        raise DecodeError(
            f"PointCloud2 on {topic!r}: {data.size} bytes for {h} rows of {row} "
            f"({w} points of {step} bytes)"
        )
    if row == w * step:
        return data[: h * row].tobytes()
    return data[: h * row].reshape(h, row)[:, : w * step].tobytes()


def cloudini(
    bag_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    resolution: float = 0.001,
    exact_fields: Sequence[str] = PACKED_COLOR,
) -> BagPeerResult:
    """The bag with every ``sensor_msgs/PointCloud2`` topic through Cloudini (``pureini``),
    every other topic as :func:`mcap_zstd` keeps it, written to an MCAP file at ``out_path``.

    The file is laid out as Cloudini's ``cloudini_rosbag_converter`` writes one: each cloud
    becomes a ``point_cloud_interfaces/msg/CompressedPointCloud2`` (same header, layout and
    ``is_dense``, ``format`` "cloudini") in the channel's own encoding, its points coded
    field by field with every float32 field quantized to ``resolution`` metres (default 1 mm:
    error at most half of it) and the other fields lossless, in 2 MiB MCAP chunks of zstd
    level 1 (so Cloudini's own second stage is off, as in the converter). Unlike the
    converter, the fields named in ``exact_fields`` (packed colour, ``rgb``/``rgba`` by
    default) are kept bit-exact: the converter quantizes them as floats too, which turns
    PCL-style packed colour to black; ``exact_fields=()`` does as the converter does.

    Raises :class:`~pcdcodec.CodecUnavailableError` without ``pureini``.
    """
    pureini = _pureini()
    bag, out = Path(bag_path), Path(out_path)
    if not (resolution > 0 and np.isfinite(resolution)):
        raise InputError(f"resolution must be a positive number of metres, got {resolution!r}")
    clouds = _Clouds()
    exact = set(exact_fields)
    converted: dict[Channel, Channel] = {}

    def channel(ch: Channel) -> Channel:
        if ch not in converted:
            store = clouds.store(ch.message_encoding)
            ros1 = ch.message_encoding == "ros1"
            text, md5 = store.generate_msgdef(CLOUDINI_SCHEMA, ros_version=1 if ros1 else 2)
            meta = dict(ch.metadata)
            if ros1:
                meta["md5sum"] = md5
            converted[ch] = Channel(
                ch.topic,
                ros1_schema(CLOUDINI_SCHEMA) if ros1 else CLOUDINI_SCHEMA,
                ch.schema_encoding if ros1 else "ros2msg",
                text.encode(),
                ch.message_encoding,
                tuple(sorted(meta.items())),
            )
        return converted[ch]

    def encode(ch: Channel, data: bytes) -> bytes:
        msg = clouds.load(data, "sensor_msgs/msg/PointCloud2", ch.message_encoding)
        fields = []
        for f in msg.fields:
            if int(f.count) > 1:
                raise InputError(
                    f"PointCloud2 on {ch.topic!r}: field {f.name!r} has count {f.count}; "
                    "Cloudini codes one value a field"
                )
            res = resolution if int(f.datatype) == 7 and f.name not in exact else None
            fields.append(
                pureini.PointField(f.name, int(f.offset), pureini.FieldType(int(f.datatype)), res)
            )
        info = pureini.EncodingInfo(
            fields=fields,
            width=int(msg.width),
            height=int(msg.height),
            point_step=int(msg.point_step),
            encoding_opt=pureini.EncodingOptions.LOSSY,
            compression_opt=pureini.CompressionOption.NONE,
        )
        try:
            packed = pureini.PointcloudEncoder(info).encode(
                _packed_rows(msg, ch.topic), is_bigendian=bool(msg.is_bigendian)
            )
        except (ValueError, RuntimeError) as exc:
            raise DecodeError(f"Cloudini cannot code the cloud on {ch.topic!r}: {exc}") from exc
        store = clouds.store(ch.message_encoding)
        compressed = store.types[CLOUDINI_SCHEMA](
            header=msg.header,
            height=msg.height,
            width=msg.width,
            fields=msg.fields,
            is_bigendian=False,
            point_step=msg.point_step,
            row_step=int(msg.point_step) * int(msg.width),
            compressed_data=np.frombuffer(packed, np.uint8),
            is_dense=msg.is_dense,
            format="cloudini",
        )
        return clouds.dump(compressed, CLOUDINI_SCHEMA, ch.message_encoding)

    def body(tmp: Path) -> int:
        count = 0
        with contextlib.ExitStack() as stack, zstd_level(ZSTD_DEFAULT_LEVEL):
            src = open_bag(bag, stack)
            with tmp.open("wb") as f:
                mcap = McapOut(f, src.profile, CLOUDINI_CHUNK_BYTES)
                for ch, log, pub, seq, data in src.records:
                    if ch.schema_name in _CLOUD_TYPES:
                        mcap.write(channel(ch), log, pub, seq, encode(ch, data))
                    else:
                        mcap.write(ch, log, pub, seq, data)
                    count += 1
                src.extras(mcap.writer)
                mcap.writer.finish()
        return count

    return _run(f"cloudini {resolution * 1000:g} mm", bag, out, body)


@dataclass(frozen=True)
class CloudBack:
    """One cloud given back by :func:`cloudini_clouds`: its topic, log time, and its points
    as an H × W structured array of the cloud's fields at their offsets (``point_step`` bytes a
    point, little-endian)."""

    topic: str
    log_time: int
    points: npt.NDArray[Any]


def write_cloud_bag(
    path: str | os.PathLike[str],
    depths: Sequence[npt.NDArray[Any]],
    colors: Sequence[npt.NDArray[np.uint8]],
    camera: CameraIntrinsics,
    depth_scale: float,
    *,
    fmt: str = "rosbag2",
    storage: str = "mcap",
    hz: float = 15.0,
    topic: str = "/camera/depth/color/points",
) -> Path:
    """A bag at ``path`` of organized XYZRGB PointCloud2 clouds (PCL's 32-byte points, NaN
    where there is no depth) made from ``depths`` and ``colors`` at ``hz``, with a ``/tf``
    message beside each: the cloud topic Cloudini is made for, in a bag of ``fmt``
    (``rosbag1``, ``rosbag2``) and ``storage`` (``mcap``, ``sqlite3``). Returns ``path``."""
    from ..geometry.projector import Projector
    from ..ros.bagwriter import BagWriter, MessageBuilder
    from ..ros.clouds import cloud_array

    projector = Projector(camera, depth_scale=depth_scale)
    out = Path(path)
    bag = BagWriter(out, fmt, storage, MessageBuilder(fmt == "rosbag2", "camera"))
    try:
        bag.add(topic, "sensor_msgs/msg/PointCloud2")
        bag.add("/tf", "tf2_msgs/msg/TFMessage")
        period = round(1e9 / hz)
        for i, (depth, color) in enumerate(zip(depths, colors, strict=True)):
            ns = (i + 1) * period
            bag.write(topic, ns, bag.messages.cloud(ns, cloud_array(projector, depth, color)))
            bag.write("/tf", ns + 1, bag.messages.tf(ns, np.eye(4), "world"))
    except BaseException:
        bag.abort()
        raise
    bag.close()
    return out


_NUMPY = {1: "i1", 2: "u1", 3: "<i2", 4: "<u2", 5: "<i4", 6: "<u4", 7: "<f4", 8: "<f8"}


def cloudini_clouds(path: str | os.PathLike[str]) -> Iterator[CloudBack]:
    """The point clouds of an MCAP file :func:`cloudini` wrote, decoded, in the file's order.

    Raises :class:`~pcdcodec.CodecUnavailableError` without ``pureini`` and
    :class:`~pcdcodec.DecodeError` for a cloud Cloudini cannot decode.
    """
    pureini = _pureini()
    clouds = _Clouds()
    decoder = pureini.PointcloudDecoder()
    with contextlib.ExitStack() as stack:
        src = open_bag(Path(path), stack)
        for ch, log, _pub, _seq, data in src.records:
            if ch.schema_name not in (CLOUDINI_SCHEMA, ros1_schema(CLOUDINI_SCHEMA)):
                continue
            msg = clouds.load(data, CLOUDINI_SCHEMA, ch.message_encoding)
            try:
                raw, info = decoder.decode(bytes(np.asarray(msg.compressed_data, np.uint8)))
            except (ValueError, RuntimeError) as exc:
                raise DecodeError(f"cannot decode the cloud on {ch.topic!r}: {exc}") from exc
            dtype = np.dtype(
                {
                    "names": [f.name for f in msg.fields],
                    "formats": [_NUMPY[int(f.datatype)] for f in msg.fields],
                    "offsets": [int(f.offset) for f in msg.fields],
                    "itemsize": int(info.point_step),
                }
            )
            h, w = int(info.height), int(info.width)
            if len(raw) != h * w * dtype.itemsize:
                raise DecodeError(
                    f"the cloud on {ch.topic!r} decodes to {len(raw)} bytes, not {h}×{w} points"
                )
            yield CloudBack(ch.topic, log, np.frombuffer(raw, dtype).reshape(h, w))
