"""The codec registry: kinds kept apart, lookups, errors, plugins through entry points."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

import pcdcodec
from pcdcodec import registry
from pcdcodec.depth import FrameCodec


@pytest.fixture
def clean_registry() -> Iterator[None]:
    """Undo any registration a test makes."""
    pcdcodec.list_codecs()
    saved = {kind: dict(table) for kind, table in registry._registry.items()}
    yield
    for kind, table in saved.items():
        registry._registry[kind].clear()
        registry._registry[kind].update(table)


class Negate(FrameCodec):
    """A toy codec: stores the bitwise complement of the pixels."""

    name: ClassVar[str] = "test-negate"

    def __init__(self, *, flag: bool = False) -> None:
        self.flag = flag

    def _encode_body(self, image: np.ndarray[Any, Any]) -> bytes:
        return bytes((~image).data)

    def _decode_body(self, body: memoryview, shape: tuple[int, int], dtype: Any) -> Any:
        return ~np.frombuffer(body, dtype).reshape(shape)


def test_kinds_are_kept_apart() -> None:
    depth = pcdcodec.list_codecs("depth")
    color = pcdcodec.list_codecs("color")
    assert "jpegxl" in depth
    assert not set(depth) & set(color)
    assert sorted(depth + color) == pcdcodec.list_codecs()
    assert depth == sorted(depth)


def test_unknown_kind_is_rejected() -> None:
    with pytest.raises(pcdcodec.InputError, match="'video'"):
        pcdcodec.list_codecs("video")


def test_unknown_name_names_it_and_lists_known_of_that_kind() -> None:
    with pytest.raises(pcdcodec.UnknownCodecError) as info:
        pcdcodec.get_codec("lz5", kind="depth")
    message = str(info.value)
    assert "'lz5'" in message
    for name in pcdcodec.list_codecs("depth"):
        assert name in message
    assert isinstance(info.value, LookupError)
    assert isinstance(info.value, pcdcodec.PcdcodecError)


def test_wrong_kind_is_an_unknown_codec() -> None:
    with pytest.raises(pcdcodec.UnknownCodecError, match="'zstd' is a depth codec"):
        pcdcodec.get_codec("zstd", kind="color")


def test_get_codec_by_name_and_by_config_agree() -> None:
    by_name = pcdcodec.get_codec("zstd", level=9)
    by_config = pcdcodec.get_codec({"id": "zstd", "level": 9})
    assert by_name == by_config
    assert by_name != pcdcodec.get_codec("zstd")
    assert by_name.get_config() == {"id": "zstd", "level": 9}


def test_config_without_id_or_mixed_with_params_is_rejected() -> None:
    with pytest.raises(pcdcodec.InputError, match="'id'"):
        pcdcodec.get_codec({"level": 3})
    with pytest.raises(pcdcodec.InputError, match="not both"):
        pcdcodec.get_codec({"id": "zstd"}, level=3)


@pytest.mark.parametrize(
    ("name", "params", "match"),
    [
        ("zstd", {"level": 99}, "99"),
        ("zstd", {"level": "high"}, "str"),
        ("lz4", {"level": -1}, "-1"),
        ("png16", {"level": 10}, "10"),
        ("jpegxl", {"effort": 0}, "effort"),
        ("jpegxl", {"threads": 0}, "threads"),
    ],
)
def test_bad_parameters_name_the_value(name: str, params: dict[str, Any], match: str) -> None:
    with pytest.raises(pcdcodec.InputError, match=match):
        pcdcodec.get_codec(name, **params)


@pytest.mark.usefixtures("clean_registry")
def test_register_codec_adds_a_working_codec() -> None:
    assert pcdcodec.register_codec(Negate) is Negate
    assert "test-negate" in pcdcodec.list_codecs("depth")
    codec = pcdcodec.get_codec({"id": "test-negate", "flag": True})
    depth = np.arange(12, dtype=np.uint16).reshape(3, 4)
    np.testing.assert_array_equal(codec.decode(codec.encode(depth)), depth)
    # A second class under the same name is refused unless replacing is asked for.
    other = type("Other", (Negate,), {})
    with pytest.raises(pcdcodec.InputError, match="already registered"):
        pcdcodec.register_codec(other)
    pcdcodec.register_codec(other, replace=True)
    assert pcdcodec.codec_class("test-negate") is other


@pytest.mark.usefixtures("clean_registry")
def test_register_rejects_non_codecs_and_taken_names_across_kinds() -> None:
    with pytest.raises(pcdcodec.InputTypeError):
        pcdcodec.register_codec(dict)  # type: ignore[arg-type]
    clash = type("Clash", (Negate,), {"name": "zstd"})
    with pytest.raises(pcdcodec.InputError, match="'zstd' is already registered"):
        pcdcodec.register_codec(clash)


@pytest.mark.usefixtures("clean_registry")
def test_missing_backend_says_what_to_install() -> None:
    class NeedsPlugin(Negate):
        name: ClassVar[str] = "test-needs-plugin"
        install_hint: ClassVar[str] = "pip install some-backend"

        @classmethod
        def unavailable_reason(cls) -> str | None:
            return "some-backend is not installed"

    pcdcodec.register_codec(NeedsPlugin)
    assert "test-needs-plugin" in pcdcodec.list_codecs("depth")
    assert "test-needs-plugin" not in pcdcodec.list_codecs("depth", available_only=True)
    codec = pcdcodec.get_codec("test-needs-plugin")
    with pytest.raises(pcdcodec.CodecUnavailableError, match="pip install some-backend") as info:
        codec.encode(np.zeros((2, 2), np.uint16))
    assert isinstance(info.value, ImportError)


def test_entry_point_codecs_are_found(tmp_path: Path) -> None:
    """A codec installed by another package is found through the entry-point group."""
    (tmp_path / "plugin_codec.py").write_text(
        textwrap.dedent(
            """
            import numpy as np
            from pcdcodec.depth import FrameCodec

            class Plain(FrameCodec):
                name = "plugin-plain"

                def __init__(self):
                    pass

                def _encode_body(self, image):
                    return image.tobytes()

                def _decode_body(self, body, shape, dtype):
                    return np.frombuffer(body, dtype).reshape(shape)
            """
        )
    )
    dist = tmp_path / "plugin_codec-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: plugin-codec\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[pcdcodec.codecs]\nplain = plugin_codec:Plain\n")
    script = textwrap.dedent(
        """
        import json, sys, numpy as np, pcdcodec
        codec = pcdcodec.get_codec("plugin-plain")
        depth = np.arange(6, dtype=np.uint16).reshape(2, 3)
        ok = bool((codec.decode(codec.encode(depth)) == depth).all())
        print(json.dumps({"names": pcdcodec.list_codecs("depth"), "ok": ok}))
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script],
        env={"PYTHONPATH": str(tmp_path), "PATH": ""},
        capture_output=True,
        text=True,
        check=True,
    )
    result = json.loads(out.stdout)
    assert "plugin-plain" in result["names"]
    assert result["ok"] is True


def test_import_does_not_load_heavy_backends() -> None:
    script = (
        "import sys, pcdcodec\n"
        "pcdcodec.list_codecs()\n"
        "print(','.join(m for m in ('open3d', 'av', 'cv2') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_codec_option_errors_name_the_value_given() -> None:
    from pcdcodec.registry import parse_codec_spec

    with pytest.raises(pcdcodec.InputTypeError, match=r"av1 gop must be an int, got '1;crf=52'"):
        parse_codec_spec("av1:gop=1;crf=52", kind="color")
    with pytest.raises(pcdcodec.InputTypeError, match=r"h264 crf must be a number, got 'abc'"):
        parse_codec_spec("h264:crf=abc", kind="color")
    with pytest.raises(pcdcodec.InputError, match="'gop' is given twice"):
        parse_codec_spec("av1:gop=1,crf=40,gop=2", kind="color")
    # A recorded config keeps true/false: 1 is not taken for True.
    with pytest.raises(
        pcdcodec.InputError, match=r"low_delay must be one of \[True, False\], got 1"
    ):
        parse_codec_spec("av1:low_delay=1", kind="color")
    assert parse_codec_spec("av1:low_delay=true", kind="color").get_config()["low_delay"] is True


def test_a_depth_type_the_codec_does_not_take_gets_a_way_out() -> None:
    metres = np.full((4, 4), 1.5, np.float32)
    with pytest.raises(pcdcodec.InputTypeError, match="lz4, zstd, jpegxl, depthac"):
        pcdcodec.get_codec("rvl").encode(metres)
    with pytest.raises(pcdcodec.InputTypeError, match=r"astype\(np.float32\)"):
        pcdcodec.get_codec("zstd").encode(metres.astype(np.float64))
