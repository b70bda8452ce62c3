"""The codec registry: names to codec classes, one table per kind.

Built-in codecs are registered when the registry is first used. Codecs from other packages are
found through the entry-point group ``pcdcodec.codecs``; each entry point names a
:class:`~pcdcodec.codec.Codec` subclass::

    [project.entry-points."pcdcodec.codecs"]
    mycodec = "mypackage.codecs:MyCodec"
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Mapping
from typing import Any

from .codec import KINDS, Codec
from .errors import InputError, InputTypeError, UnknownCodecError

__all__ = [
    "ENTRY_POINT_GROUP",
    "codec_class",
    "codec_for_reading",
    "get_codec",
    "list_codecs",
    "parse_codec_spec",
    "parse_codec_specs",
    "register_codec",
]

ENTRY_POINT_GROUP = "pcdcodec.codecs"

_registry: dict[str, dict[str, type[Codec]]] = {kind: {} for kind in KINDS}
_lock = threading.RLock()
_loaded = False


def register_codec(cls: type[Codec], *, replace: bool = False) -> type[Codec]:
    """Add a codec class to the registry under ``cls.name``; usable as a class decorator.

    Names are unique across kinds, so a config's ``"id"`` alone identifies its codec.
    Registering a taken name raises :class:`~pcdcodec.InputError` unless ``replace=True``.
    """
    if not (isinstance(cls, type) and issubclass(cls, Codec)):
        raise InputTypeError(f"register_codec expects a Codec subclass, got {cls!r}")
    name = getattr(cls, "name", None)
    kind = getattr(cls, "kind", None)
    if not isinstance(name, str) or not name:
        raise InputError(f"codec class {cls.__qualname__} must set a non-empty string 'name'")
    if kind not in KINDS:
        raise InputError(f"codec {name!r} has kind {kind!r}, expected one of {list(KINDS)}")
    with _lock:
        for other_kind, table in _registry.items():
            existing = table.get(name)
            if (
                existing is not None
                and existing is not cls
                and not (replace and other_kind == kind)
            ):
                raise InputError(
                    f"codec name {name!r} is already registered as {other_kind} codec "
                    f"{existing.__module__}.{existing.__qualname__}"
                )
        _registry[kind][name] = cls
    return cls


def _ensure_loaded() -> None:
    global _loaded
    if _loaded:
        return
    with _lock:
        if _loaded:
            return
        _loaded = True
        # The built-in codecs registered themselves when pcdcodec/__init__ imported the depth and
        # color packages (importing this module imports pcdcodec first); plugins load here.
        _load_entry_points()


def _load_entry_points() -> None:
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            cls = ep.load()
            register_codec(cls)
        except Exception as exc:  # a broken plugin must not break the library
            warnings.warn(
                f"could not load codec entry point {ep.name!r} ({ep.value}): {exc}",
                RuntimeWarning,
                stacklevel=3,
            )


def _check_kind(kind: str | None) -> None:
    if kind is not None and kind not in KINDS:
        raise InputError(f"kind must be one of {list(KINDS)}, got {kind!r}")


def list_codecs(kind: str | None = None, *, available_only: bool = False) -> list[str]:
    """Registered codec names of ``kind`` (``"depth"`` or ``"color"``), or of all kinds, sorted.

    With ``available_only=True``, codecs whose backend library is missing are left out.
    """
    _check_kind(kind)
    _ensure_loaded()
    kinds = KINDS if kind is None else (kind,)
    names = [
        name
        for k in kinds
        for name, cls in _registry[k].items()
        if not available_only or cls.is_available()
    ]
    return sorted(names)


def codec_class(name: str, kind: str | None = None) -> type[Codec]:
    """The class registered under ``name``, optionally required to be of ``kind``."""
    _check_kind(kind)
    _ensure_loaded()
    if not isinstance(name, str):
        raise InputTypeError(f"codec name must be a string, got {type(name).__name__}")
    for k in KINDS:
        cls = _registry[k].get(name)
        if cls is None:
            continue
        if kind is not None and k != kind:
            raise UnknownCodecError(
                f"{name!r} is a {k} codec, expected a {kind} codec; "
                f"known {kind} codecs: {', '.join(list_codecs(kind)) or '(none)'}"
            )
        return cls
    kinds = KINDS if kind is None else (kind,)
    known = "; ".join(f"{k}: {', '.join(list_codecs(k)) or '(none)'}" for k in kinds)
    raise UnknownCodecError(f"unknown codec {name!r}; known codecs are {known}")


def get_codec(
    name_or_config: str | Mapping[str, Any], /, *, kind: str | None = None, **params: Any
) -> Codec:
    """Build a codec from its name and parameters, or from a config dict.

    ``get_codec("zstd", level=9)`` and ``get_codec({"id": "zstd", "level": 9})`` are equal.
    ``kind`` restricts the lookup to ``"depth"`` or ``"color"`` codecs.

    Raises :class:`~pcdcodec.UnknownCodecError` for an unknown name (the message lists the known
    ones), :class:`~pcdcodec.InputError` for a bad parameter and
    :class:`~pcdcodec.CodecUnavailableError` when the codec's backend library is missing.
    """
    if isinstance(name_or_config, Mapping):
        if params:
            raise InputError("pass either a config dict or keyword parameters, not both")
        config = dict(name_or_config)
        if "id" not in config:
            raise InputError(f"codec config must have an 'id' key, got keys {sorted(config)}")
        cls = codec_class(config["id"], kind)
        return cls.from_config(config)
    cls = codec_class(name_or_config, kind)
    return cls.from_config({"id": cls.name, **params})


def parse_codec_spec(spec: str, kind: str | None = None) -> Codec:
    """A codec from a command-line spec: ``"h264"`` or ``"h264:crf=20,preset=fast"``.

    Values are read as JSON where they parse (numbers, ``true``/``false``/``null``), else as
    strings. Raises :class:`~pcdcodec.InputError` for an option that is not ``key=value`` and
    the errors of :func:`get_codec` for unknown codecs or parameters.
    """
    import json

    name, _, rest = spec.partition(":")
    params: dict[str, Any] = {}
    for item in filter(None, rest.split(",")):
        key, eq, value = item.partition("=")
        if not eq:
            raise InputError(f"codec option {item!r} in {spec!r} is not key=value")
        if key.strip() in params:
            raise InputError(f"codec option {key.strip()!r} is given twice in {spec!r}")
        try:
            params[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            params[key.strip()] = value
    return get_codec(name.strip(), kind=kind, **params)


def parse_codec_specs(text: str, kind: str | None = None) -> list[Codec]:
    """Codecs from a comma-separated list of specs: ``"zstd:level=9,lz4,h264:crf=20,preset=fast"``
    (an item with ``=`` but no ``:`` continues the options of the codec before it)."""
    specs: list[str] = []
    for item in (part.strip() for part in text.split(",")):
        if not item:
            continue
        if "=" in item and ":" not in item and specs:
            specs[-1] += "," + item
        else:
            specs.append(item)
    if not specs:
        raise InputError(f"no codec in {text!r}")
    return [parse_codec_spec(s, kind) for s in specs]


def codec_for_reading(
    config: Mapping[str, Any], /, *, kind: str | None = None, threads: int | None = None
) -> Codec:
    """The codec a file's recorded ``config`` describes, with this machine's settings.

    Runtime parameters (:attr:`Codec.runtime_params`, such as ``threads``) are a property of the
    machine, not of the data: any the file recorded (older files did) are dropped, and
    ``threads`` applies to the codecs that take it (``None``: the codec's default).
    """
    codec = get_codec(config, kind=kind)
    stored = codec.stored_config()
    if threads is not None and "threads" in codec.runtime_params:
        stored["threads"] = threads
    return get_codec(stored, kind=kind)


def as_codec(spec: Any, kind: str) -> Codec:
    """The ``kind`` codec ``spec`` names: a codec (checked to be of that kind), a name, a
    ``"name:key=value"`` spec or a config dict. Raises :class:`InputError` for a codec of the other
    kind and :class:`InputTypeError` for anything else."""
    if isinstance(spec, Codec):
        if spec.kind != kind:
            raise InputError(f"{spec.name!r} is a {spec.kind} codec, expected a {kind} codec")
        return spec
    if isinstance(spec, str) and ":" in spec:
        return parse_codec_spec(spec, kind)  # "depthac:max_rel_error=0.005"
    if isinstance(spec, (str, dict)):
        return get_codec(spec, kind=kind)
    raise InputTypeError(
        f"{kind} codec must be a name, a config dict or a codec, got {type(spec).__name__}"
    )
