"""The depth codecs as Zarr format 3 codecs: array-to-bytes codecs (serializers) named
``pcdcodec.<name>``.

A depth codec turns an image into bytes, so in a Zarr v3 array it takes the place of the
``bytes`` serializer (a bytes-to-bytes compressor would see a flat buffer without the image's
shape). Each chunk must be one image: a chunk shape of ``(1, ..., 1, H, W)``; the array's
dtype must be one the codec takes (uint16, or float32 metres for the codecs that take it).
Both are checked when the array is created, with :class:`~pcdcodec.InputError`. Chunks at the
array's edge are padded to the chunk shape with the fill value by Zarr, so any array shape works.

The array's metadata records ``{"name": "pcdcodec.<name>", "configuration": {...}}`` with the
codec's stored parameters (the bound options among them); Zarr finds the class again through
the ``zarr.codecs`` entry points, or once this module is imported.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..depth import FrameCodec
from ..errors import CodecUnavailableError, DecodeError, InputError, InputTypeError
from ..registry import as_codec, list_codecs

try:
    import zarr.registry
    from zarr.abc.codec import ArrayBytesCodec
    from zarr.core.chunk_grids import RegularChunkGrid
except ImportError:  # the optional extra is not installed, or Zarr is older than 3
    raise CodecUnavailableError(
        "pcdcodec's Zarr codecs need zarr 3 (Python 3.11 or newer): pip install 'pcdcodec[zarr]'"
    ) from None

if TYPE_CHECKING:
    from typing_extensions import Self
    from zarr.core.array_spec import ArraySpec
    from zarr.core.buffer import Buffer, NDBuffer

__all__ = ["PREFIX", "DepthSerializer", "register", "serializer"]

#: What a pcdcodec codec's name is prefixed with in Zarr codec names.
PREFIX = "pcdcodec."


def _native_dtype(dtype: Any) -> np.dtype[Any]:
    """The numpy dtype of a Zarr data type (a ``ZDType`` since zarr 3.1)."""
    to_native = getattr(dtype, "to_native_dtype", None)
    native: np.dtype[Any] = np.dtype(to_native() if to_native is not None else dtype)
    return native


def _image_shape(chunk_shape: tuple[int, ...], name: str) -> tuple[int, int]:
    """The (H, W) of a chunk of one image; :class:`InputError` for any other chunk shape."""
    if len(chunk_shape) < 2 or any(n != 1 for n in chunk_shape[:-2]):
        raise InputError(
            f"Zarr codec {name} codes one depth image per chunk, so chunks must be of shape "
            f"(1, ..., 1, H, W); got chunk shape {tuple(chunk_shape)} (for a T×H×W array use "
            "chunks=(1, H, W))"
        )
    return (int(chunk_shape[-2]), int(chunk_shape[-1]))


@dataclass(frozen=True)
class DepthSerializer(ArrayBytesCodec):
    """A pcdcodec depth codec as a Zarr v3 array-to-bytes codec.

    ``codec`` is a depth codec's name (``"depthac"`` or ``"pcdcodec.depthac"``), a
    ``"name:key=value"`` spec, a config dict or a :class:`~pcdcodec.depth.FrameCodec`;
    ``params`` are its parameters, e.g. ``DepthSerializer("depthac", max_rel_error=0.005)``.
    """

    is_fixed_size = False

    codec: FrameCodec

    def __init__(self, codec: str | Mapping[str, Any] | FrameCodec = "depthac", **params: Any):
        if params:
            if not isinstance(codec, str) or ":" in codec:
                raise InputError("pass parameters either in the codec or as keywords, not both")
            codec = {"id": codec.removeprefix(PREFIX), **params}
        elif isinstance(codec, str):
            codec = codec.removeprefix(PREFIX)
        built = as_codec(dict(codec) if isinstance(codec, Mapping) else codec, "depth")
        if not isinstance(built, FrameCodec):
            raise InputTypeError(f"Zarr codec needs a depth frame codec, got {built!r}")
        object.__setattr__(self, "codec", built)

    @property
    def name(self) -> str:
        """The codec's name in Zarr metadata: ``"pcdcodec.<name>"``."""
        return PREFIX + self.codec.name

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Self:
        """The codec of a Zarr metadata entry ``{"name": ..., "configuration": {...}}``."""
        name = data.get("name")
        if not isinstance(name, str) or not name.startswith(PREFIX):
            raise InputError(f"not a pcdcodec Zarr codec: name {name!r}, expected 'pcdcodec.*'")
        config = data.get("configuration") or {}
        if not isinstance(config, Mapping):
            raise InputTypeError(f"Zarr codec {name} configuration must be a mapping: {config!r}")
        return cls({**config, "id": name.removeprefix(PREFIX)})

    def to_dict(self) -> dict[str, Any]:
        """The metadata entry: the name and the stored parameters (no machine settings)."""
        config = self.codec.stored_config()
        del config["id"]
        return {"name": self.name, "configuration": config}

    def validate(self, *, shape: tuple[int, ...], dtype: Any, chunk_grid: Any) -> None:
        """Refuse, when the array is created, a dtype the codec does not take and chunks that
        are not one image each."""
        native = _native_dtype(dtype)
        if native.kind not in "uf" or native.name not in self.codec.dtypes:
            raise InputTypeError(
                f"Zarr codec {self.name} takes arrays of {' or '.join(self.codec.dtypes)}, "
                f"got {native}"
            )
        if not isinstance(chunk_grid, RegularChunkGrid):
            kind = type(chunk_grid).__name__
            raise InputError(f"Zarr codec {self.name} needs a regular chunk grid, got {kind}")
        _image_shape(chunk_grid.chunk_shape, self.name)

    def compute_encoded_size(self, input_byte_length: int, chunk_spec: ArraySpec) -> int:
        raise NotImplementedError  # the size depends on the image

    def _encode_chunk(self, chunk: npt.NDArray[Any], shape: tuple[int, ...]) -> bytes:
        image = chunk.reshape(_image_shape(shape, self.name))
        return self.codec.encode(image)

    def _decode_chunk(self, data: bytes, shape: tuple[int, ...], dtype: Any) -> npt.NDArray[Any]:
        hw = _image_shape(shape, self.name)
        image = self.codec.decode(data, shape=hw, max_pixels=None)
        native = _native_dtype(dtype)
        if image.dtype.kind != native.kind or image.dtype.itemsize != native.itemsize:
            raise DecodeError(
                f"Zarr chunk holds a {image.dtype.name} depth image, the array is {native}"
            )
        return image.astype(native, copy=False).reshape(shape)

    async def _encode_single(self, chunk_array: NDBuffer, chunk_spec: ArraySpec) -> Buffer | None:
        chunk = chunk_array.as_numpy_array()
        data = await asyncio.to_thread(self._encode_chunk, chunk, chunk_spec.shape)
        out: Buffer = chunk_spec.prototype.buffer.from_bytes(data)
        return out

    async def _decode_single(self, chunk_bytes: Buffer, chunk_spec: ArraySpec) -> NDBuffer:
        data = chunk_bytes.to_bytes()
        image = await asyncio.to_thread(
            self._decode_chunk, data, chunk_spec.shape, chunk_spec.dtype
        )
        out: NDBuffer = chunk_spec.prototype.nd_buffer.from_numpy_array(image)
        return out


def serializer(codec: str | Mapping[str, Any] | FrameCodec = "depthac", **params: Any) -> Any:
    """The Zarr v3 serializer of a depth codec: ``zarr.create_array(...,
    serializer=serializer("depthac"), compressors=None)``. Arguments as :class:`DepthSerializer`.
    """
    return DepthSerializer(codec, **params)


def register() -> None:
    """Register :class:`DepthSerializer` with Zarr under ``pcdcodec.<name>`` for every depth
    codec, plugins included (done on import; call again after registering a codec)."""
    for name in list_codecs("depth"):
        zarr.registry.register_codec(PREFIX + name, DepthSerializer)


register()
