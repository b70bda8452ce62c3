"""The frame codec base and the byte container every depth codec writes.

The container (documented in ``docs/format.md``) wraps the codec's body with a header that
names the codec, the dtype and shape of the image, the body length and a CRC-32 of the header
and of the decoded image. Decoding checks all of it, so corrupt, truncated or foreign bytes
raise :class:`~pcdcodec.DecodeError` instead of returning wrong depth.
"""

from __future__ import annotations

import struct
import zlib
from abc import abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from .._validate import check_depth
from ..codec import Codec
from ..errors import DecodeError, InputError, InputTypeError

__all__ = [
    "DEFAULT_MAX_PIXELS",
    "FORMAT_VERSION",
    "MAGIC",
    "FrameCodec",
    "FrameHeader",
    "check_frame_size",
    "read_header",
]

MAGIC = b"PCDF"
FORMAT_VERSION = 1

_DTYPE_CODES: dict[int, np.dtype[Any]] = {1: np.dtype("<u2"), 2: np.dtype("<f4")}
_CODE_OF_DTYPE = {v.str: k for k, v in _DTYPE_CODES.items()}

#: How the image was turned into what the codec body holds.
LAYOUT_DIRECT = 0  # the image itself
LAYOUT_TABLE = 1  # float32: a table of distinct values + a uint16 index image
LAYOUT_PLANES = 2  # float32: high and low 16-bit halves stacked as a (2H, W) uint16 image
LAYOUT_BOUNDED = 3  # lossy within a stated error: lattice parameters + a level index image

#: The most pixels :meth:`FrameCodec.decode` accepts unless told otherwise: 8192 × 8192, a
#: 128 MiB uint16 or 256 MiB float32 image, well above any depth camera. A frame header is only
#: a few bytes, so without a limit a tiny hostile frame could ask for gigabytes.
DEFAULT_MAX_PIXELS = 8192 * 8192

_FIXED = struct.Struct("<4sBBBB")  # magic, version, dtype code, layout, name length
_TAIL = struct.Struct("<IIQI")  # height, width, body length, crc32


@dataclass(frozen=True)
class FrameHeader:
    """The decoded header of an encoded depth frame."""

    codec: str
    dtype: np.dtype[Any]
    layout: int
    height: int
    width: int
    body_length: int
    checksum: int
    header_size: int

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)


def _pack_header(
    codec: str, dtype: np.dtype[Any], layout: int, shape: tuple[int, int], body_len: int
) -> bytes:
    name = codec.encode("ascii")
    return (
        _FIXED.pack(MAGIC, FORMAT_VERSION, _CODE_OF_DTYPE[dtype.str], layout, len(name))
        + name
        + struct.pack("<IIQ", shape[0], shape[1], body_len)
    )


def read_header(data: bytes | bytearray | memoryview) -> FrameHeader:
    """Parse and check the header of an encoded depth frame (not the body)."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise InputTypeError(f"encoded depth must be bytes-like, got {type(data).__name__}")
    mv = memoryview(data)
    if mv.nbytes < _FIXED.size:
        raise DecodeError(f"encoded depth is truncated: {mv.nbytes} bytes, shorter than any header")
    magic, version, dcode, layout, nlen = _FIXED.unpack_from(mv, 0)
    if magic != MAGIC:
        raise DecodeError(
            f"not a pcdcodec depth frame: starts with {bytes(magic)!r}, expected {MAGIC!r}"
        )
    if version != FORMAT_VERSION:
        raise DecodeError(
            f"depth frame format version {version} is not supported (this pcdcodec reads "
            f"version {FORMAT_VERSION}); a newer pcdcodec may read it"
        )
    if dcode not in _DTYPE_CODES:
        raise DecodeError(f"depth frame has unknown dtype code {dcode}")
    if layout not in (LAYOUT_DIRECT, LAYOUT_TABLE, LAYOUT_PLANES, LAYOUT_BOUNDED):
        raise DecodeError(f"depth frame has unknown layout code {layout}")
    header_size = _FIXED.size + nlen + _TAIL.size
    if mv.nbytes < header_size:
        raise DecodeError(
            f"encoded depth is truncated: {mv.nbytes} bytes, header needs {header_size}"
        )
    try:
        name = bytes(mv[_FIXED.size : _FIXED.size + nlen]).decode("ascii")
    except UnicodeDecodeError:
        raise DecodeError("depth frame header holds a codec name that is not ASCII") from None
    height, width, body_len, crc = _TAIL.unpack_from(mv, _FIXED.size + nlen)
    if height == 0 or width == 0:
        raise DecodeError(f"depth frame header has an empty shape ({height}, {width})")
    if mv.nbytes != header_size + body_len:
        state = "truncated" if mv.nbytes < header_size + body_len else "followed by extra bytes"
        raise DecodeError(
            f"encoded depth is {state}: {mv.nbytes} bytes, header says {header_size + body_len}"
        )
    return FrameHeader(name, _DTYPE_CODES[dcode], layout, height, width, body_len, crc, header_size)


def check_frame_size(
    header: FrameHeader,
    *,
    shape: tuple[int, int] | None = None,
    max_pixels: int | None = DEFAULT_MAX_PIXELS,
) -> None:
    """Raise :class:`~pcdcodec.DecodeError` when a frame is not of ``shape`` or has more than
    ``max_pixels`` pixels (``None``: no limit), before anything is decompressed."""
    if shape is not None and header.shape != tuple(shape):
        raise DecodeError(
            f"depth frame is {header.width}x{header.height}, expected {shape[1]}x{shape[0]}"
        )
    if max_pixels is not None and header.height * header.width > max_pixels:
        raise DecodeError(
            f"depth frame declares {header.width}x{header.height} = "
            f"{header.height * header.width} pixels, more than the limit of {max_pixels}; "
            "pass max_pixels= to decode larger frames"
        )


def _float_to_table(
    image: npt.NDArray[np.float32],
) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint16]] | None:
    """Map float32 values to indices into a table of their distinct bit patterns.

    NaN patterns come first, so "no measurement" gets the small indices; the rest keep bit order,
    which for non-negative floats is value order, so the index image is as smooth as the depth.
    Returns ``None`` when there are more than 65536 distinct values.
    """
    bits = image.view(np.uint32).ravel()
    from ._table_kernels import distinct_values

    found, first, status = distinct_values(bits, 65536)
    if status == 1:
        return None
    if status == 0:
        # Sort the few distinct values, then carry each pixel's position through the sort.
        order = np.argsort(found)
        position = np.empty(order.size, dtype=np.int64)
        position[order] = np.arange(order.size)
        table, inverse = found[order], position[first]
    else:
        table, inverse = np.unique(bits, return_inverse=True)
        if table.size > 65536:
            return None
    is_nan = (table & 0x7F800000 == 0x7F800000) & (table & 0x007FFFFF != 0)
    if is_nan.any():
        order = np.argsort(~is_nan, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(order.size)
        table = table[order]
        inverse = rank[inverse]
    return table, inverse.astype(np.uint16).reshape(image.shape)


def _pack_table(table: npt.NDArray[np.uint32]) -> bytes:
    import zstandard

    # Sorted runs make small deltas; uint32 wrap-around keeps it exact for the NaN prefix too.
    deltas = np.diff(table, prepend=np.uint32(0)).astype("<u4")
    return zstandard.ZstdCompressor(level=9).compress(deltas.tobytes())


def _unpack_table(data: memoryview, count_limit: int = 65536) -> npt.NDArray[np.uint32]:
    import zstandard

    raw = zstandard.ZstdDecompressor().decompress(bytes(data), max_output_size=4 * count_limit)
    if len(raw) % 4 or not raw:
        raise DecodeError(f"float value table has {len(raw)} bytes, not a positive multiple of 4")
    return np.cumsum(np.frombuffer(raw, "<u4"), dtype=np.uint32)


_BOUND_PARAMS = ("max_error", "max_rel_error")


class FrameCodec(Codec):
    """Base of depth codecs: one depth image to self-describing bytes, and back.

    Subclasses implement :meth:`_encode_body` and :meth:`_decode_body` for the dtypes in
    :attr:`native_dtypes`. When ``"float32"`` is in :attr:`dtypes` but not native, float32
    depth is carried losslessly through a table of its distinct values (``docs/format.md``).

    Codecs that take ``max_error`` / ``max_rel_error`` (and pass them to :meth:`_set_bound`)
    store depth lossily within that bound when one is given (:mod:`pcdcodec.depth.bounded`):
    every valid pixel decodes within ``max(max_error, max_rel_error · depth)``, in depth units
    for uint16 and metres for float32; holes stay holes. Without a bound they are lossless.
    """

    kind: ClassVar[str] = "depth"
    #: Tolerance, in level indices, of the codec's own near-lossless coding of bounded-error
    #: index images (0: the index image is coded losslessly).
    bounded_near: ClassVar[int] = 0
    max_error: float | None = None
    max_rel_error: float | None = None

    @property
    def lossless(self) -> bool:
        """Whether decoding gives back exactly what was encoded (no error bound is set)."""
        return self._bound() is None

    @property
    def error_bound(self) -> Any:
        """The :class:`~pcdcodec.depth.bounded.ErrorBound` in force, or ``None`` (lossless)."""
        return self._bound()

    def _set_bound(self, max_error: Any, max_rel_error: Any) -> None:
        """Validate and store the error bound options (``None``: lossless)."""
        from .bounded import check_bound

        self.max_error, self.max_rel_error = check_bound(
            max_error, max_rel_error, codec=f"codec {self.name!r}"
        )

    def _bound(self) -> Any:
        """The :class:`~pcdcodec.depth.bounded.ErrorBound` in force, or ``None`` (lossless)."""
        a = self.max_error or 0.0
        r = self.max_rel_error or 0.0
        if a == 0 and r == 0:
            return None
        from .bounded import ErrorBound

        return ErrorBound(a, r)

    def get_config(self) -> dict[str, Any]:
        """As :meth:`Codec.get_config`, leaving out error bounds that are not set, so lossless
        configs stay as they always were."""
        config = super().get_config()
        for pname in _BOUND_PARAMS:
            if config.get(pname, 0) is None:
                del config[pname]
        return config

    def _encode_levels(
        self, index: npt.NDArray[np.uint16], near: int
    ) -> tuple[bytes, npt.NDArray[np.uint16]]:
        """Code a level index image (0 = hole) with tolerance ``near``; returns the body and
        the index image the decoder will see. Codecs with near-lossless coding override it."""
        if near:
            raise InputError(f"codec {self.name!r} has no near-lossless coding")
        return self._encode_body(index), index

    def _decode_levels(
        self, body: memoryview, shape: tuple[int, int], near: int
    ) -> npt.NDArray[np.uint16]:
        if near:
            raise DecodeError(f"codec {self.name!r} has no near-lossless coding (near {near})")
        u16 = np.dtype("<u2")
        return self._check_image(self._decode_body(body, shape, u16), shape, u16)

    #: Depth dtypes :meth:`encode` accepts.
    dtypes: ClassVar[tuple[str, ...]] = ("uint16",)
    #: Dtypes the body codec handles itself; others in :attr:`dtypes` go through a mapping.
    native_dtypes: ClassVar[tuple[str, ...]] = ("uint16",)

    @abstractmethod
    def _encode_body(self, image: npt.NDArray[Any]) -> bytes:
        """Compress a C-contiguous little-endian 2-D image of a native dtype."""

    @abstractmethod
    def _decode_body(
        self, body: memoryview, shape: tuple[int, int], dtype: np.dtype[Any]
    ) -> npt.NDArray[Any]:
        """Decompress a body into an image of ``shape`` and ``dtype``; may raise anything."""

    # -- public API ----------------------------------------------------------------------

    def encode(self, depth: npt.ArrayLike) -> bytes:
        """Encode one depth image.

        ``depth`` is a 2-D uint16 image in depth units (0 = no measurement) or, where the codec
        supports it (see :attr:`dtypes`), a float32 image in metres with NaN for no measurement.
        Raises :class:`~pcdcodec.InputError` / :class:`~pcdcodec.InputTypeError` for other input.
        """
        self._require_available()
        image = check_depth(depth, allowed=self.dtypes, name=f"depth for codec {self.name!r}")
        return self.encode_checked(image)

    def encode_checked(self, image: npt.NDArray[Any]) -> bytes:
        """:meth:`encode` past its checks, for a caller that checked the image already: ``image``
        is what :func:`pcdcodec._validate.check_depth` returned for this codec's :attr:`dtypes`
        (2-D, non-empty, C-contiguous) and the codec is available. A recording's writer checks
        each frame once, where it is handed in, and encodes it with this."""
        bound = self._bound()
        if bound is not None:
            bounded = self._encode_bounded(image, bound)
            if bounded is not None:
                return bounded
        layout = LAYOUT_DIRECT
        prefix = b""
        work = image
        dname = "uint16" if image.dtype.kind == "u" else "float32"
        if dname not in self.native_dtypes:
            mapped = _float_to_table(image)
            if mapped is not None:
                table, work = mapped
                layout = LAYOUT_TABLE
                packed = _pack_table(table)
                prefix = struct.pack("<I", len(packed)) + packed
            else:
                layout = LAYOUT_PLANES
                bits = image.view("<u4")
                work = np.concatenate([(bits >> 16).astype("<u2"), (bits & 0xFFFF).astype("<u2")])
        body = prefix + self._encode_body(work)
        header = _pack_header(self.name, image.dtype, layout, image.shape, len(body))
        crc = zlib.crc32(image.data, zlib.crc32(header))
        return header + struct.pack("<I", crc) + body

    def _encode_bounded(self, image: npt.NDArray[Any], bound: Any) -> bytes | None:
        """The bounded-error frame of ``image``, or ``None`` where no level table of at most
        65,535 levels keeps the bound (then the frame is coded losslessly, which keeps it too).

        Tolerances from :attr:`bounded_near` down to 0 are tried in turn; at 0 the levels are
        fitted to the frame (uint16 always, float32 when it has at most 65,535 distinct values).
        """
        from .bounded import (
            KIND_F32_FRAME,
            KIND_F32_LATTICE,
            KIND_U16_FRAME,
            KIND_U16_LATTICE,
            LatticeParams,
            float_frame_levels,
            frame_levels,
            quantise_float,
            uint16_lattice,
        )

        is_float = image.dtype.kind == "f"
        hole_bits = 0
        if is_float:
            valid = np.isfinite(image) & (image > 0)
            holes = image.view("<u4")[~valid]
            if not valid.any() or (holes.size and np.any(holes != holes[0])):
                return None  # nothing to quantise, or mixed kinds of holes: keep them exact
            hole_bits = int(holes[0]) if holes.size else 0x7FC00000
        table: npt.NDArray[Any] | None
        for near in range(self.bounded_near, -1, -1):
            kind = KIND_F32_LATTICE if is_float else KIND_U16_LATTICE
            stored = b""  # the levels, for a float32 frame that carries its own
            fitted_float = (
                float_frame_levels(image, valid, bound) if is_float and near == 0 else None
            )
            if fitted_float is not None:
                levels32, index = fitted_float
                kind, si = KIND_F32_FRAME, 0
                lo, hi, nlevels = float(levels32[0]), float(levels32[-1]), levels32.size
                table = np.concatenate([np.zeros(1, dtype=np.float32), levels32])
                packed = _pack_table(levels32.view("<u4"))
                stored = struct.pack("<I", len(packed)) + packed
            elif not is_float and near == 0:
                # Coded exactly, levels fitted to the frame's own values beat any fixed table.
                fitted = frame_levels(image, bound)
                if fitted is None:
                    continue
                index, nlevels = fitted
                kind, si, lo, hi = KIND_U16_FRAME, 0, 1.0, 65535.0
                table = None  # the index image holds the levels themselves
            elif is_float:
                mapped = quantise_float(image, valid, bound, near)
                if mapped is None:
                    continue
                si, lo, hi, table, index = mapped
                nlevels = table.size - 1
            else:
                lattice = uint16_lattice(bound, near)
                if lattice is None:
                    continue
                si, table, lut = lattice
                lo, hi, nlevels = 1.0, 65535.0, table.size - 1
                index = lut[image]
            body, recon = self._encode_levels(index, near)
            if is_float and table is not None:
                # The coder may pick any level of the window: check the decoded values.
                got = table[recon[valid]].astype(np.float64)
                want = image[valid].astype(np.float64)
                if not np.all(np.abs(got - want) <= bound.of(want)):
                    continue
            params = LatticeParams(
                kind,
                near,
                si,
                bound.abs_error,
                bound.rel_error,
                lo,
                hi,
                hole_bits,
                nlevels,
            ).pack()
            params += stored
            header = _pack_header(
                self.name, image.dtype, LAYOUT_BOUNDED, image.shape, len(params) + len(body)
            )
            crc = zlib.crc32(recon.data, zlib.crc32(params, zlib.crc32(header)))
            return header + struct.pack("<I", crc) + params + body
        return None

    def decode(
        self,
        data: bytes | bytearray | memoryview,
        *,
        shape: tuple[int, int] | None = None,
        max_pixels: int | None = DEFAULT_MAX_PIXELS,
    ) -> npt.NDArray[Any]:
        """Decode bytes written by :meth:`encode` back into the exact depth image.

        Memory is bounded by what the frame's header declares: a frame of more than
        ``max_pixels`` pixels (default :data:`DEFAULT_MAX_PIXELS`, 8192 × 8192; ``None`` for no
        limit), or not of ``shape`` (height, width) when given, is refused before anything is
        decompressed, and no codec body may decompress into more than the header's size.

        Raises :class:`~pcdcodec.DecodeError` when the bytes are corrupt, truncated, too large,
        of another format version, or were written by another codec.
        """
        self._require_available()
        header = read_header(data)
        if header.codec != self.name:
            raise DecodeError(
                f"depth frame was written by codec {header.codec!r}, not {self.name!r}; "
                "pcdcodec.decode_depth() picks the right codec from the bytes"
            )
        check_frame_size(header, shape=shape, max_pixels=max_pixels)
        body = memoryview(data)[header.header_size :]
        head = bytes(memoryview(data)[: header.header_size - 4])
        if header.layout == LAYOUT_BOUNDED:
            return self._decode_bounded(header, head, body)
        try:
            image = self._decode_layout(header, body)
        except DecodeError:
            raise
        except Exception as exc:  # backend libraries raise all sorts of things
            raise DecodeError(
                f"codec {self.name!r} could not decode a {header.width}x{header.height} "
                f"{header.dtype.name} frame: {type(exc).__name__}: {exc}"
            ) from exc
        crc = zlib.crc32(image.data, zlib.crc32(head))
        if crc != header.checksum:
            raise DecodeError(
                f"checksum mismatch in a {header.width}x{header.height} {self.name!r} depth frame "
                f"(stored {header.checksum:#010x}, decoded {crc:#010x}): the data is corrupt"
            )
        return image

    def _decode_bounded(
        self, header: FrameHeader, head: bytes, body: memoryview
    ) -> npt.NDArray[Any]:
        from .bounded import KIND_F32_FRAME, PARAMS_SIZE, LatticeParams, decode_levels

        params = LatticeParams.unpack(body)
        if params.is_float != (header.dtype.kind == "f"):
            raise DecodeError(
                f"bounded-error frame of {header.dtype.name} depth holds a "
                f"{'float32' if params.is_float else 'uint16'} lattice"
            )
        start = PARAMS_SIZE
        stored = None
        if params.kind == KIND_F32_FRAME:
            if len(body) < start + 4:
                raise DecodeError("bounded-error frame is truncated inside its level table")
            (tlen,) = struct.unpack_from("<I", body, start)
            if start + 4 + tlen > len(body):
                raise DecodeError(f"level table length {tlen} runs past the end of the frame")
            try:
                stored = _unpack_table(body[start + 4 : start + 4 + tlen]).view("<f4")
            except DecodeError:
                raise
            except Exception as exc:  # zstandard's errors
                raise DecodeError(f"bounded-error frame has a corrupt level table: {exc}") from exc
            start += 4 + tlen
        try:
            index = self._decode_levels(body[start:], header.shape, params.near)
        except DecodeError:
            raise
        except Exception as exc:  # backend libraries raise all sorts of things
            raise DecodeError(
                f"codec {self.name!r} could not decode a {header.width}x{header.height} "
                f"bounded-error frame: {type(exc).__name__}: {exc}"
            ) from exc
        crc = zlib.crc32(index.data, zlib.crc32(body[:start], zlib.crc32(head)))
        if crc != header.checksum:
            raise DecodeError(
                f"checksum mismatch in a {header.width}x{header.height} {self.name!r} "
                f"bounded-error depth frame (stored {header.checksum:#010x}, decoded "
                f"{crc:#010x}): the data is corrupt"
            )
        return decode_levels(params, index, header.dtype, stored)

    def _decode_layout(self, header: FrameHeader, body: memoryview) -> npt.NDArray[Any]:
        shape = header.shape
        if header.layout == LAYOUT_DIRECT:
            dname = "uint16" if header.dtype.kind == "u" else "float32"
            if dname not in self.native_dtypes:
                raise DecodeError(f"codec {self.name!r} cannot hold {dname} depth directly")
            return self._check_image(
                self._decode_body(body, shape, header.dtype), shape, header.dtype
            )
        if header.dtype.kind != "f":
            raise DecodeError(f"layout {header.layout} is only valid for float32 depth")
        u16 = np.dtype("<u2")
        if header.layout == LAYOUT_TABLE:
            if len(body) < 4:
                raise DecodeError("float value table is truncated")
            (tlen,) = struct.unpack_from("<I", body, 0)
            if 4 + tlen > len(body):
                raise DecodeError(f"float value table length {tlen} runs past the end of the frame")
            table = _unpack_table(body[4 : 4 + tlen])
            index = self._check_image(self._decode_body(body[4 + tlen :], shape, u16), shape, u16)
            if index.max() >= table.size:
                raise DecodeError(
                    f"float index {int(index.max())} is outside the value table of {table.size}"
                )
            values: npt.NDArray[np.float32] = table[index].view("<f4")
            return values
        planes_shape = (2 * shape[0], shape[1])
        planes = self._check_image(self._decode_body(body, planes_shape, u16), planes_shape, u16)
        bits = (planes[: shape[0]].astype("<u4") << 16) | planes[shape[0] :]
        floats: npt.NDArray[np.float32] = bits.view("<f4")
        return floats

    @staticmethod
    def _check_image(image: Any, shape: tuple[int, int], dtype: np.dtype[Any]) -> npt.NDArray[Any]:
        arr = np.asarray(image)
        if (
            arr.shape != shape
            or arr.dtype.kind != dtype.kind
            or arr.dtype.itemsize != dtype.itemsize
        ):
            raise DecodeError(
                f"decoded body is {arr.dtype} {arr.shape}, header says {dtype.name} {shape}"
            )
        arr = np.ascontiguousarray(arr, dtype=dtype)
        return arr if arr.flags.writeable else arr.copy()


def bytes_body(
    raw: bytes | bytearray, shape: tuple[int, int], dtype: np.dtype[Any]
) -> npt.NDArray[Any]:
    """Turn decompressed raw bytes into an image, checking the length first."""
    expected = shape[0] * shape[1] * dtype.itemsize
    if len(raw) != expected:
        raise DecodeError(
            f"decompressed {len(raw)} bytes, expected {expected} for {dtype.name} {shape}"
        )
    return np.frombuffer(raw, dtype).reshape(shape)
