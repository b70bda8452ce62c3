"""The depth codecs as numcodecs codecs, with ids ``pcdcodec.<name>``.

One class per depth codec, registered with numcodecs when this module is imported and listed in
the ``numcodecs.codecs`` entry points of pcdcodec's package metadata, so
``numcodecs.get_codec({"id": "pcdcodec.depthac"})`` works without importing pcdcodec first.
A codec registered later (a plugin) gets its class from :func:`numcodec_class`.

``encode`` takes one depth image: a 2-D array, or one with leading axes of length 1 (a Zarr
chunk of one frame, ``(1, H, W)``); ``decode`` returns the 2-D image, or fills ``out``.

A Zarr format 2 array does not tell its compressor the chunk's shape and dtype: it views what
``decode`` returns as the array's dtype and reshapes it to the chunk's shape. So a chunk holding
an image of another shape or dtype (a 64x48 frame in a 48x64 array, float32 in a uint16 array)
must not pass those steps: ``decode`` returns a :class:`DecodedImage`, a numpy array that raises
:class:`~pcdcodec.DecodeError` when it is reshaped into an image of another shape or dtype than
the one decoded, and ``out`` is checked the same way. ``np.asarray(image)`` is a plain array. The
config is the codec's :meth:`~pcdcodec.codec.Codec.stored_config` under the numcodecs id, so
bound options (``max_error``, ``max_rel_error``) are recorded and machine settings
(``threads``) are not.
"""

from __future__ import annotations

import threading
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from ..depth import FrameCodec
from ..errors import CodecUnavailableError, DecodeError, InputError, InputTypeError
from ..registry import codec_class, get_codec

try:
    import numcodecs.abc
    import numcodecs.compat
    import numcodecs.registry
except ImportError:  # the optional extra is not installed
    raise CodecUnavailableError(
        "pcdcodec's numcodecs codecs need numcodecs: pip install 'pcdcodec[zarr]'"
    ) from None

__all__ = [
    "JPEGXL",
    "LZ4",
    "PNG16",
    "PREFIX",
    "RVL",
    "DecodedImage",
    "DepthAC",
    "DepthNumcodec",
    "Zstd",
    "as_image",
    "numcodec",
    "numcodec_class",
]

#: What a pcdcodec codec's name is prefixed with in numcodecs ids and Zarr codec names.
PREFIX = "pcdcodec."


def as_image(buf: Any, codec_id: str) -> npt.NDArray[Any]:
    """The 2-D depth image in ``buf``: an array of shape ``(H, W)`` or ``(1, ..., 1, H, W)``.

    Raises :class:`~pcdcodec.InputError` for any other shape, naming ``codec_id``: a flat byte
    buffer has lost the image's shape, and a chunk of several frames is not one image.
    """
    arr = numcodecs.compat.ensure_ndarray_like(buf)
    if arr.ndim < 2 or any(n != 1 for n in arr.shape[:-2]):
        where = (
            "a flat buffer has no image shape: use the codec as a Zarr v3 array's serializer "
            "or a Zarr v2 array's compressor, not after another codec"
            if arr.ndim < 2
            else "chunk the array one frame per chunk, e.g. chunks=(1, H, W)"
        )
        raise InputError(
            f"{codec_id} encodes one depth image of shape (H, W) or (1, ..., 1, H, W), got "
            f"shape {tuple(arr.shape)}; {where}"
        )
    if arr.flags.f_contiguous and not arr.flags.c_contiguous:
        # Zarr format 2 takes what decode() returns as the chunk's bytes in the array's order.
        raise InputError(
            f"{codec_id} takes depth in C order, got an array in Fortran order: a Zarr format 2 "
            "array of order 'F' would read back scrambled; create it with order='C', or pass "
            "np.ascontiguousarray(depth)"
        )
    image: npt.NDArray[Any] = np.asarray(arr).reshape(arr.shape[-2:])
    if image.dtype.byteorder == ">" or (image.dtype.byteorder == "=" and _BIG_ENDIAN):
        # Zarr format 2 views what decode() returns (little-endian) as the array's dtype.
        raise InputTypeError(
            f"{codec_id} takes little-endian depth, got {image.dtype.str}: a Zarr format 2 array "
            f"of it would read back byte-swapped; store it as {image.dtype.newbyteorder('<').str}"
        )
    return image


_BIG_ENDIAN = np.dtype("=u2").str[0] == ">"


def _image_mismatch(
    image: tuple[tuple[int, ...], np.dtype[Any]],
    shape: tuple[int, ...],
    dtype: np.dtype[Any],
    order: str = "C",
) -> str | None:
    """Why an image of ``image`` (shape, dtype) cannot be read as an array of ``shape`` and
    ``dtype`` in ``order``, or ``None`` when it can. Axes of length 1 do not count, so a chunk
    ``(1, H, W)`` holds an ``H x W`` image."""
    ishape, idtype = image
    if dtype.kind != idtype.kind or dtype.itemsize != idtype.itemsize:
        return f"it holds a {idtype.name} depth image, the array is {dtype}"
    if dtype.str != idtype.str:
        return f"it holds a {idtype.str} depth image, the array is {dtype.str} (byte-swapped)"
    if [n for n in shape if n != 1] != [n for n in ishape if n != 1]:
        return (
            f"it holds a {ishape[0]}x{ishape[1]} depth image, the array's chunk is "
            f"{'x'.join(map(str, shape))}"
        )
    if order == "F" and sum(n != 1 for n in ishape) > 1:
        return "a depth image reads back scrambled into an array of order 'F'"
    return None


def _target_shape(size: int, args: tuple[Any, ...]) -> tuple[int, ...]:
    """The shape ``ndarray.reshape(*args)`` asks for, with a ``-1`` worked out."""
    shape = args[0] if len(args) == 1 and not isinstance(args[0], (int, np.integer)) else args
    dims = [int(n) for n in shape]
    if dims.count(-1) == 1:
        known = int(np.prod([n for n in dims if n != -1]))
        dims[dims.index(-1)] = size // known if known else 0
    return tuple(dims)


class DecodedImage(np.ndarray):
    """A decoded depth image that refuses to become an image of another shape or dtype.

    What ``decode`` returns without ``out``. It is a numpy array in every way, except that
    reshaping it (or a view of it) to two or more axes raises :class:`~pcdcodec.DecodeError`
    unless the result is the decoded image itself: same dtype, and the same ``H x W`` up to axes
    of length 1. That is the step by which a Zarr format 2 array turns a chunk into its pixels,
    so a chunk holding another image fails there instead of reading back scrambled.
    ``np.asarray(image)`` is a plain array.
    """

    _decoded: tuple[tuple[int, ...], np.dtype[Any]] | None
    _codec_id: str

    @classmethod
    def of(cls, image: npt.NDArray[Any], codec_id: str) -> DecodedImage:
        out = image.view(cls)
        out._decoded = (image.shape, image.dtype)
        out._codec_id = codec_id
        return out

    def __array_finalize__(self, obj: Any) -> None:
        # Only view() and reshape() keep what the image was decoded as (_kept); a slice, a
        # computation or astype() of it is a plain array.
        self._decoded = None
        self._codec_id = ""

    def _kept(self, result: Any) -> Any:
        if isinstance(result, DecodedImage):
            result._decoded = self._decoded
            result._codec_id = self._codec_id
        return result

    def view(self, *args: Any, **kwargs: Any) -> Any:
        return self._kept(super().view(*args, **kwargs))

    def reshape(self, *shape: Any, order: Any = "C") -> Any:  # type: ignore[override]
        target = _target_shape(self.size, shape)
        decoded = self._decoded
        if decoded is None:
            return super().reshape(*shape, order=order)
        if len(target) < 2:
            return self._kept(super().reshape(*shape, order=order))
        why = _image_mismatch(decoded, target, self.dtype, "F" if order == "F" else "C")
        if why is None and int(np.prod(target)) != self.size:
            why = f"its {self.size} values do not fill a chunk of {target}"
        if why is not None:
            raise DecodeError(f"{self._codec_id}: this Zarr chunk does not fit the array: {why}")
        return np.asarray(super().reshape(*shape, order=order))


def _fill(image: npt.NDArray[Any], out: Any, codec_id: str) -> Any:
    """``image`` copied into ``out``: by value into an array of its dtype (in any byte order
    and memory layout, of its shape up to axes of length 1), as raw bytes into a byte buffer."""
    try:
        dest = numcodecs.compat.ensure_ndarray_like(out)
    except (TypeError, ValueError) as e:
        raise InputTypeError(f"{codec_id}: out must be a writeable array or buffer: {e}") from None
    if not dest.flags.writeable:
        kind = type(out).__name__
        raise InputTypeError(f"{codec_id}: out must be writeable, got a read-only {kind}")
    wanted = f"the decoded {image.shape[0]}x{image.shape[1]} {image.dtype} image"
    if dest.nbytes != image.nbytes:
        raise InputError(
            f"{codec_id}: out holds {dest.nbytes} bytes ({dest.dtype} {tuple(dest.shape)}), "
            f"{wanted} needs {image.nbytes}"
        )
    if dest.dtype.itemsize == 1:
        return numcodecs.compat.ndarray_copy(image, out)
    if dest.dtype.kind != image.dtype.kind or dest.dtype.itemsize != image.dtype.itemsize:
        raise InputTypeError(f"{codec_id}: out is {dest.dtype}, {wanted} is {image.dtype}")
    if [n for n in dest.shape if n != 1] != [n for n in image.shape if n != 1]:
        # Zarr format 2 decodes a whole chunk straight into the array: its shape is the chunk's.
        raise DecodeError(
            f"{codec_id}: out is {tuple(dest.shape)}, the chunk holds a "
            f"{image.shape[0]}x{image.shape[1]} depth image: it is not this array's chunk"
        )
    np.copyto(dest, image.reshape(dest.shape))
    return out


class DepthNumcodec(numcodecs.abc.Codec):  # type: ignore[misc]  # numcodecs is untyped
    """A pcdcodec depth codec as a numcodecs codec; subclasses set :attr:`codec_id`.

    Keyword parameters are the depth codec's own (``pcdcodec.get_codec(name, **params)``),
    checked when the codec is built.
    """

    #: ``"pcdcodec." + name``, the numcodecs id.
    codec_id: ClassVar[str]

    def __init__(self, **params: Any) -> None:
        codec = get_codec(self.codec_id.removeprefix(PREFIX), kind="depth", **params)
        if not isinstance(codec, FrameCodec):
            raise InputTypeError(f"{self.codec_id} is not a frame codec: {codec!r}")
        self._codec = codec

    @property
    def codec(self) -> FrameCodec:
        """The pcdcodec depth codec doing the work."""
        return self._codec

    def encode(self, buf: Any) -> bytes:
        """One depth image (see :func:`as_image`) to the codec's self-describing bytes."""
        return self._codec.encode(as_image(buf, self.codec_id))

    def decode(self, buf: Any, out: Any = None) -> Any:
        """The depth image in ``buf`` as a :class:`DecodedImage`; copied into ``out`` (of its
        shape and dtype, up to axes of length 1) when given."""
        try:
            data = numcodecs.compat.ensure_contiguous_ndarray(buf)
        except (TypeError, ValueError) as e:
            raise InputTypeError(
                f"{self.codec_id} decodes a contiguous bytes-like buffer, got "
                f"{type(buf).__name__}: {e}"
            ) from None
        image = self._codec.decode(memoryview(data).cast("B"))
        if out is None:
            return DecodedImage.of(image, self.codec_id)
        return _fill(image, out, self.codec_id)

    def get_config(self) -> dict[str, Any]:
        """The numcodecs id and the depth codec's stored parameters (no machine settings)."""
        config = self._codec.stored_config()
        config["id"] = self.codec_id
        return config

    @classmethod
    def from_config(cls, config: dict[str, Any]) -> DepthNumcodec:
        """The codec :meth:`get_config` describes (its ``id``, if present, must match)."""
        params = dict(config)
        cid = params.pop("id", cls.codec_id)
        if cid != cls.codec_id:
            raise InputError(f"config id {cid!r} does not match numcodecs codec {cls.codec_id!r}")
        return cls(**params)

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.get_config().items() if k != "id")
        return f"{type(self).__name__}({params})"

    def __reduce__(self) -> tuple[Any, ...]:
        # By id and full config (machine settings too), so classes made for plugins pickle.
        return (_rebuild, (self.codec_id, self._codec.get_config()))


def _rebuild(codec_id: str, config: dict[str, Any]) -> DepthNumcodec:
    params = {k: v for k, v in config.items() if k != "id"}
    return numcodec_class(codec_id)(**params)


class DepthAC(DepthNumcodec):
    """``pcdcodec.depthac``: pcdcodec's own lossless depth coder (``max_error``,
    ``max_rel_error`` for bounded error)."""

    codec_id: ClassVar[str] = PREFIX + "depthac"


class JPEGXL(DepthNumcodec):
    """``pcdcodec.jpegxl``: lossless JPEG XL (``effort``; ``threads`` is not recorded)."""

    codec_id: ClassVar[str] = PREFIX + "jpegxl"


class PNG16(DepthNumcodec):
    """``pcdcodec.png16``: a 16-bit PNG (``level``)."""

    codec_id: ClassVar[str] = PREFIX + "png16"


class RVL(DepthNumcodec):
    """``pcdcodec.rvl``: run-length and variable-length coding of depth."""

    codec_id: ClassVar[str] = PREFIX + "rvl"


class Zstd(DepthNumcodec):
    """``pcdcodec.zstd``: the raw image through Zstandard (``level``)."""

    codec_id: ClassVar[str] = PREFIX + "zstd"


class LZ4(DepthNumcodec):
    """``pcdcodec.lz4``: the raw image through LZ4 (``level``)."""

    codec_id: ClassVar[str] = PREFIX + "lz4"


_CLASSES: dict[str, type[DepthNumcodec]] = {
    cls.codec_id: cls for cls in (DepthAC, JPEGXL, PNG16, RVL, Zstd, LZ4)
}
_lock = threading.Lock()


def numcodec_class(name: str) -> type[DepthNumcodec]:
    """The numcodecs class of depth codec ``name`` (``"depthac"`` or ``"pcdcodec.depthac"``),
    made and registered with numcodecs on first use for codecs beyond the built-in ones.

    Raises :class:`~pcdcodec.UnknownCodecError` when no depth codec has that name.
    """
    if not isinstance(name, str):
        raise InputTypeError(f"codec name must be a string, got {type(name).__name__}")
    short = name.removeprefix(PREFIX)
    codec_class(short, "depth")  # raises for unknown names and color codecs
    with _lock:
        cls = _CLASSES.get(PREFIX + short)
        if cls is None:
            cls = type(
                f"Numcodec_{short}",
                (DepthNumcodec,),
                {"codec_id": PREFIX + short, "__doc__": f"``{PREFIX}{short}`` for numcodecs."},
            )
            _CLASSES[cls.codec_id] = cls
            numcodecs.registry.register_codec(cls)
    return cls


def numcodec(name: str = "depthac", **params: Any) -> DepthNumcodec:
    """A numcodecs codec of depth codec ``name`` with its parameters, e.g.
    ``numcodec("depthac", max_rel_error=0.005)``."""
    return numcodec_class(name)(**params)


for _cls in _CLASSES.values():
    numcodecs.registry.register_codec(_cls)
