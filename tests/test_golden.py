"""Golden files: committed frames of every built-in depth codec decode to the same depth forever."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import pcdcodec

from .golden.make_golden import golden_source

GOLDEN = Path(__file__).resolve().parent / "golden" / "depth"
BUILTIN_DEPTH = [
    n
    for n in pcdcodec.list_codecs("depth")
    if pcdcodec.codec_class(n).__module__.startswith("pcdcodec.")
]


@pytest.mark.parametrize("name", BUILTIN_DEPTH)
def test_golden_frames_decode_exactly(name: str) -> None:
    index_path = GOLDEN / f"{name}.json"
    assert index_path.exists(), f"no golden frames for {name}: run tests/golden/make_golden.py"
    index = json.loads(index_path.read_text())
    codec = pcdcodec.get_codec(index["config"])
    assert codec.get_config() == index["config"]
    assert len(index["frames"]) >= 2
    for entry in index["frames"]:
        data = (GOLDEN / entry["file"]).read_bytes()
        expected = golden_source(entry)
        decoded = codec.decode(data)
        assert decoded.dtype == expected.dtype
        view = np.uint32 if expected.dtype.itemsize == 4 else np.uint16
        np.testing.assert_array_equal(
            decoded.view(view), expected.view(view), err_msg=entry["file"]
        )
        assert pcdcodec.decode_depth(data).shape == expected.shape
