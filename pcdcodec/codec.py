"""Codec base classes.

A codec is a small object with a registered ``name``, a ``kind`` and its parameters as plain
public attributes. Its configuration, :meth:`Codec.get_config`, is a JSON-only dict holding the
``"id"`` and every parameter; :func:`pcdcodec.get_codec` turns such a dict back into an equal
codec, so anything written with a codec can be read back from its config alone.

Two kinds exist and are kept apart:

* ``"depth"`` codecs are *frame codecs* (:class:`pcdcodec.depth.FrameCodec`): one depth image in,
  one self-describing ``bytes`` object out, and back. No state is kept between frames.
* ``"color"`` codecs (:class:`ColorCodec`) encode video. Most are *stream codecs*
  (:class:`pcdcodec.color.StreamCodec`): encoders that keep state across frames and emit packets.
"""

from __future__ import annotations

import inspect
from abc import ABC
from typing import Any, ClassVar

from .errors import CodecUnavailableError, InputError

__all__ = ["KINDS", "Codec", "ColorCodec"]

#: The codec kinds, in the order they are listed.
KINDS: tuple[str, ...] = ("depth", "color")

_JSON_SCALARS = (str, int, float, bool, type(None))


class Codec(ABC):
    """Base of every codec.

    Subclasses set the class attributes :attr:`name` and :attr:`kind` and take their parameters
    as keyword arguments of ``__init__``, stored under the same names as public attributes.
    The parameter list is read from the ``__init__`` signature, so :meth:`get_config`,
    :meth:`from_config`, equality, hashing and ``repr`` need no code in the subclass.
    """

    #: Registered name; the ``"id"`` of the config.
    name: ClassVar[str]
    #: ``"depth"`` or ``"color"``.
    kind: ClassVar[str]
    #: What to install when :meth:`unavailable_reason` is not ``None``.
    install_hint: ClassVar[str] = ""

    # -- availability ------------------------------------------------------------------

    @classmethod
    def unavailable_reason(cls) -> str | None:
        """Why this codec cannot run here, or ``None`` when it can."""
        return None

    @classmethod
    def is_available(cls) -> bool:
        """True when the backend library this codec needs can be used on this machine."""
        return cls.unavailable_reason() is None

    @classmethod
    def _require_available(cls) -> None:
        reason = cls.unavailable_reason()
        if reason is not None:
            hint = f"; {cls.install_hint}" if cls.install_hint else ""
            raise CodecUnavailableError(f"codec {cls.name!r} is unavailable: {reason}{hint}")

    # -- configuration -------------------------------------------------------------------

    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        """Names of the parameters, in ``__init__`` order."""
        cached = cls.__dict__.get("_param_names_cache")
        if cached is None:
            sig = inspect.signature(cls.__init__)
            cached = tuple(
                p.name
                for p in sig.parameters.values()
                if p.name != "self" and p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)
            )
            cls._param_names_cache = cached  # type: ignore[attr-defined]
        return cached

    #: Parameters that belong to the machine, not to the data (worker threads): they are kept
    #: out of the configs written into files (:meth:`stored_config`), and whoever reads a file
    #: chooses their own (:func:`pcdcodec.registry.codec_for_reading`).
    runtime_params: ClassVar[tuple[str, ...]] = ()

    def stored_config(self) -> dict[str, Any]:
        """What a file records about this codec: :meth:`get_config` without
        :attr:`runtime_params`."""
        config = self.get_config()
        for pname in self.runtime_params:
            config.pop(pname, None)
        return config

    def get_config(self) -> dict[str, Any]:
        """A JSON-serialisable dict with ``"id"`` and every parameter of this codec."""
        config: dict[str, Any] = {"id": self.name}
        for pname in self.param_names():
            value = getattr(self, pname)
            if isinstance(value, tuple):
                value = list(value)
            if not isinstance(value, (*_JSON_SCALARS, list)):
                raise TypeError(
                    f"parameter {pname!r} of codec {self.name!r} is not "
                    f"JSON-serialisable: {value!r}"
                )
            config[pname] = value
        return config

    @classmethod
    def from_config(cls, config: dict[str, Any]) -> Codec:
        """Build the codec described by ``config`` (as returned by :meth:`get_config`)."""
        params = dict(config)
        cid = params.pop("id", cls.name)
        if cid != cls.name:
            raise InputError(f"config id {cid!r} does not match codec {cls.name!r}")
        unknown = sorted(set(params) - set(cls.param_names()))
        if unknown:
            raise InputError(
                f"codec {cls.name!r} has no parameter {unknown[0]!r}; "
                f"its parameters are {list(cls.param_names())}"
            )
        return cls(**params)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Codec):
            return NotImplemented
        return type(self) is type(other) and self.get_config() == other.get_config()

    def __hash__(self) -> int:
        return hash((type(self), repr(self)))

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.get_config().items() if k != "id")
        return f"{type(self).__name__}({params})"


class ColorCodec(Codec):
    """Base of color codecs: packet stream codecs (:class:`pcdcodec.color.StreamCodec`) and
    whole-file video codecs (:class:`pcdcodec.color.FileVideoCodec`)."""

    kind: ClassVar[str] = "color"
    #: Whether decoding gives back exactly the RGB bytes that were encoded.
    lossless: ClassVar[bool] = False

    def keyframe_interval(self, fps: float) -> int:
        """Frames from one keyframe to the next at ``fps`` (1: every frame decodes on its own).
        A stream may be cut only at keyframes."""
        return 1
