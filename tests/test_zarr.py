"""Depth codecs in numcodecs and in Zarr arrays: round trips on real frames, configs that rebuild
the codec, the bound options, the entry points, and the chunk shapes refused."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.depth import FrameCodec

from .conftest import REPO, SEQUENCES, SHARED_SEQUENCES, load_depths, to_metres

numcodecs = pytest.importorskip("numcodecs")

from pcdcodec.zarr import numcodecs as pz_numcodecs  # noqa: E402  (needs numcodecs)

DEPTH_CODECS = pcdcodec.list_codecs("depth")


def _zarr() -> Any:
    """zarr 3, or a skip (it needs Python 3.11)."""
    zarr = pytest.importorskip("zarr")
    if int(zarr.__version__.split(".")[0]) < 3:
        pytest.skip(f"zarr {zarr.__version__} is older than 3")
    return zarr


def _dtypes(name: str) -> tuple[str, ...]:
    codec = pcdcodec.get_codec(name, kind="depth")
    assert isinstance(codec, FrameCodec)
    return codec.dtypes


def assert_bit_exact(decoded: np.ndarray[Any, Any], original: np.ndarray[Any, Any]) -> None:
    assert decoded.shape == original.shape
    assert decoded.dtype == original.dtype
    view = np.uint32 if original.dtype.itemsize == 4 else np.uint16
    np.testing.assert_array_equal(decoded.view(view), original.view(view))


def frames(sequence: str, dtype: str, count: int = 5) -> np.ndarray[Any, Any]:
    """``count`` frames of ``sequence`` as a T×H×W array: uint16 units or float32 metres."""
    depths = np.stack(load_depths(sequence, count))
    if dtype == "float32":
        return to_metres(depths, SEQUENCES[sequence].depth_scale)
    return depths


def depth_array(zarr: Any, store: Any, data: np.ndarray[Any, Any], codec: Any, **kw: Any) -> Any:
    """A Zarr v3 array of ``data``, one frame per chunk, with ``codec`` as its serializer."""
    array = zarr.create_array(
        store,
        shape=data.shape,
        chunks=kw.pop("chunks", (1, *data.shape[1:])),
        dtype=data.dtype,
        serializer=codec,
        compressors=None,
        **kw,
    )
    array[:] = data
    return array


def entry_point_path(tmp_path: Path) -> Path:
    """A folder holding the package metadata of pyproject.toml's numcodecs and zarr entry
    points, for a process that runs this checkout without installing it."""
    tomllib = pytest.importorskip("tomllib")
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    dist = tmp_path / "site" / "pcdcodec_entry_points-0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: pcdcodec-entry-points\nVersion: 0\n"
    )
    lines = []
    for group in ("numcodecs.codecs", "zarr.codecs"):
        lines.append(f"[{group}]")
        lines += [f"{k} = {v}" for k, v in project["entry-points"][group].items()]
    (dist / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return dist.parent


def run_fresh(script: str, tmp_path: Path) -> Any:
    """Run ``script`` in a new Python process that finds the entry points; its JSON output."""
    env = {"PYTHONPATH": f"{entry_point_path(tmp_path)}:{REPO}", "PATH": ""}
    out = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


# -- numcodecs ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", DEPTH_CODECS)
def test_numcodec_round_trip(name: str) -> None:
    codec = pz_numcodecs.numcodec(name)
    assert codec.codec_id == f"pcdcodec.{name}"
    for dtype in _dtypes(name):
        for depth in frames("sample", dtype, 3):
            data = codec.encode(depth)
            assert len(data) < depth.nbytes
            assert_bit_exact(codec.decode(data), depth)
            out = np.empty((1, *depth.shape), depth.dtype)  # a Zarr chunk of one frame
            codec.decode(data, out=out)
            assert_bit_exact(out[0], depth)
            assert codec.encode(depth[None]) == data


def test_numcodec_config_rebuilds_it_through_numcodecs() -> None:
    codec = pz_numcodecs.numcodec("jpegxl", effort=3, threads=2)
    config = codec.get_config()
    assert config == {"id": "pcdcodec.jpegxl", "effort": 3}  # threads belong to the machine
    rebuilt = numcodecs.get_codec(config)
    assert type(rebuilt) is pz_numcodecs.JPEGXL
    assert rebuilt == codec.__class__(effort=3)
    assert json.loads(json.dumps(config)) == config
    clone = pickle.loads(pickle.dumps(codec))
    assert clone.codec.threads == 2


def test_numcodec_refuses_what_is_not_one_image() -> None:
    codec = pz_numcodecs.numcodec("depthac")
    depth = load_depths("sample", 1)[0]
    with pytest.raises(pcdcodec.InputError, match=r"flat buffer.*serializer"):
        codec.encode(depth.tobytes())
    with pytest.raises(pcdcodec.InputError, match=r"got shape \(2, 480, 640\).*chunks=\(1, H, W\)"):
        codec.encode(np.stack([depth, depth]))
    with pytest.raises(pcdcodec.InputError, match="max_rel_error"):
        pz_numcodecs.numcodec("depthac", max_rel_error=2.0)
    with pytest.raises(pcdcodec.UnknownCodecError):
        pz_numcodecs.numcodec("h264")
    with pytest.raises(pcdcodec.InputError, match="does not match"):
        pz_numcodecs.DepthAC.from_config({"id": "pcdcodec.rvl"})


def test_numcodec_decode_checks_out_and_its_input() -> None:
    codec = pz_numcodecs.numcodec("depthac")
    depth = load_depths("sample", 1)[0]
    data = codec.encode(depth)
    swapped = np.empty(depth.shape, ">u2")
    codec.decode(data, out=swapped)  # by value, not the image's bytes seen as big-endian
    assert np.array_equal(swapped, depth)
    fortran = np.empty(depth.shape, np.uint16, order="F")
    codec.decode(data, out=fortran)
    assert np.array_equal(fortran, depth)
    raw = np.empty(depth.nbytes, np.uint8)  # a byte buffer takes the image's bytes
    codec.decode(data, out=raw)
    assert raw.tobytes() == depth.tobytes()
    with pytest.raises(pcdcodec.InputError, match=r"out holds 200 bytes.*needs 614400"):
        codec.decode(data, out=np.empty((10, 10), np.uint16))
    with pytest.raises(pcdcodec.InputError, match=r"out holds 1228800 bytes \(float32"):
        codec.decode(data, out=np.empty(depth.shape, np.float32))
    with pytest.raises(pcdcodec.InputTypeError, match="out is int16"):
        codec.decode(data, out=np.empty(depth.shape, np.int16))
    with pytest.raises(pcdcodec.InputTypeError, match="read-only bytes"):
        codec.decode(data, out=bytes(depth.nbytes))
    with pytest.raises(pcdcodec.InputTypeError, match="got str"):
        codec.decode("not bytes")
    with pytest.raises(pcdcodec.InputTypeError, match="contiguous"):
        codec.decode(np.frombuffer(data, np.uint8)[::2])


def test_numcodec_refuses_what_zarr_v2_would_read_back_swapped_or_scrambled() -> None:
    codec = pz_numcodecs.numcodec("depthac")
    depth = load_depths("sample", 1)[0]
    with pytest.raises(pcdcodec.InputTypeError, match=r"little-endian depth, got >u2.*<u2"):
        codec.encode(depth.astype(">u2"))
    with pytest.raises(pcdcodec.InputTypeError, match=r"got >f4.*<f4"):
        codec.encode(depth.astype(">f4"))
    zarr = _zarr()
    store = zarr.storage.MemoryStore()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Zarr warns that v2 arrays are not the newest format
        array = zarr.create_array(
            store,
            shape=(1, *depth.shape),
            chunks=(1, *depth.shape),
            dtype=">u2",
            zarr_format=2,
            filters=None,
            compressors=codec,
        )
        with pytest.raises(pcdcodec.InputTypeError, match="byte-swapped"):
            array[0] = depth
        fortran = zarr.create_array(
            zarr.storage.MemoryStore(),
            shape=(1, *depth.shape),
            chunks=(1, *depth.shape),
            dtype="<u2",
            order="F",
            zarr_format=2,
            filters=None,
            compressors=codec,
        )
        with pytest.raises(pcdcodec.InputError, match="order 'F' would read back scrambled"):
            fortran[0] = depth
    with pytest.raises(pcdcodec.InputError, match="Fortran order"):
        codec.encode(np.asfortranarray(depth))


def test_plugin_codec_gets_a_numcodec_class() -> None:
    from .test_registry import Negate

    pcdcodec.register_codec(Negate)
    try:
        cls = pz_numcodecs.numcodec_class("test-negate")
        assert cls is pz_numcodecs.numcodec_class("pcdcodec.test-negate")
        codec = numcodecs.get_codec({"id": "pcdcodec.test-negate", "flag": True})
        assert isinstance(codec, cls)
        depth = load_depths("sample", 1)[0]
        assert_bit_exact(pickle.loads(pickle.dumps(codec)).decode(codec.encode(depth)), depth)
    finally:
        from pcdcodec import registry

        registry._registry["depth"].pop("test-negate", None)


def test_numcodecs_finds_every_codec_by_id_without_importing_pcdcodec(tmp_path: Path) -> None:
    result = run_fresh(
        """
        import json, sys
        import numpy as np
        import numcodecs
        depth = (np.arange(48 * 64, dtype=np.uint16).reshape(48, 64) % 700) * 3
        depth[5:9, 10:30] = 0
        before = "pcdcodec" in sys.modules
        ok = {}
        for name in ("depthac", "jpegxl", "lz4", "png16", "rvl", "zstd"):
            codec = numcodecs.get_codec({"id": "pcdcodec." + name})
            ok[name] = bool((codec.decode(codec.encode(depth)) == depth).all())
        print(json.dumps({"before": before, "ok": ok, "type": type(codec).__module__}))
        """,
        tmp_path,
    )
    assert result["before"] is False
    assert result["ok"] == dict.fromkeys(DEPTH_CODECS, True)
    assert result["type"] == "pcdcodec.zarr.numcodecs"


def test_pyproject_lists_every_depth_codec() -> None:
    tomllib = pytest.importorskip("tomllib")
    groups = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["entry-points"]
    ids = [f"pcdcodec.{name}" for name in DEPTH_CODECS]
    assert sorted(groups["numcodecs.codecs"]) == ids
    assert sorted(groups["zarr.codecs"]) == ids
    for codec_id, target in groups["numcodecs.codecs"].items():
        module, _, attr = target.partition(":")
        assert module == "pcdcodec.zarr.numcodecs"
        assert getattr(pz_numcodecs, attr).codec_id == codec_id
    assert set(groups["zarr.codecs"].values()) == {"pcdcodec.zarr.v3:DepthSerializer"}


# -- Zarr format 3 -----------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", ["uint16", "float32"])
@pytest.mark.parametrize(
    "sequence",
    ["sample", *(pytest.param(s, marks=pytest.mark.shared_data) for s in SHARED_SEQUENCES)],
)
def test_zarr_round_trip_real_frames(sequence: str, dtype: str) -> None:
    zarr = _zarr()
    from pcdcodec.zarr import serializer

    data = frames(sequence, dtype)
    array = depth_array(zarr, zarr.storage.MemoryStore(), data, serializer("depthac"))
    reopened = zarr.open_array(array.store)
    assert reopened.metadata.to_dict()["codecs"] == (
        {"name": "pcdcodec.depthac", "configuration": {}},
    )
    assert_bit_exact(reopened[:], data)
    assert_bit_exact(reopened[2], data[2])  # one chunk, read on its own
    # The chunks are depthac frames, and smaller than the frames.
    assert 0 < _chunk_bytes(array) < data.nbytes / 3


@pytest.mark.parametrize("name", DEPTH_CODECS)
def test_zarr_round_trip_every_codec(name: str) -> None:
    zarr = _zarr()
    from pcdcodec.zarr import serializer

    for dtype in _dtypes(name):
        data = frames("sample", dtype, 3)
        array = depth_array(zarr, zarr.storage.MemoryStore(), data, serializer(name))
        assert_bit_exact(zarr.open_array(array.store)[:], data)


def test_zarr_metadata_rebuilds_the_codec_in_a_new_process(tmp_path: Path) -> None:
    zarr = _zarr()
    from pcdcodec.zarr import DepthSerializer, serializer

    data = frames("sample", "float32", 4)
    codec = serializer("jpegxl", effort=3, threads=2)
    depth_array(zarr, zarr.storage.LocalStore(tmp_path / "depth.zarr"), data, codec)
    np.save(tmp_path / "depth.npy", data)

    # From the JSON alone: the metadata names the codec and its stored parameters.
    meta = json.loads((tmp_path / "depth.zarr" / "zarr.json").read_text())
    entry = meta["codecs"][0]
    assert entry == {"name": "pcdcodec.jpegxl", "configuration": {"effort": 3}}
    assert zarr.registry.get_codec_class(entry["name"]).from_dict(entry) == serializer(
        "jpegxl", effort=3
    )
    assert DepthSerializer.from_dict(entry).codec == pcdcodec.get_codec("jpegxl", effort=3)

    # And in a process that has not imported pcdcodec: Zarr finds it by its name.
    result = run_fresh(
        f"""
        import json, sys, warnings
        import numpy as np, zarr
        array = zarr.open_array({str(tmp_path / "depth.zarr")!r}, mode="r")
        want = np.load({str(tmp_path / "depth.npy")!r})
        got = array[:]
        print(json.dumps({{
            "same": bool((got.view(np.uint32) == want.view(np.uint32)).all()),
            "dtype": str(got.dtype),
            "codec": type(array.serializer).__module__,
        }}))
        """,
        tmp_path,
    )
    assert result == {"same": True, "dtype": "float32", "codec": "pcdcodec.zarr.v3"}


@pytest.mark.parametrize("dtype", ["uint16", "float32"])
def test_zarr_bounded_error_keeps_its_bound(dtype: str) -> None:
    zarr = _zarr()
    from pcdcodec.zarr import serializer

    data = frames("sample", dtype, 3)
    max_error = 0.002 if dtype == "float32" else 2.0
    codec = serializer("depthac", max_error=max_error, max_rel_error=0.005)
    array = depth_array(zarr, zarr.storage.MemoryStore(), data, codec)
    reopened = zarr.open_array(array.store)
    assert reopened.metadata.to_dict()["codecs"][0]["configuration"] == {
        "max_error": max_error,
        "max_rel_error": 0.005,
    }
    got = reopened[:]
    assert got.dtype == data.dtype
    valid = data > 0 if dtype == "uint16" else np.isfinite(data)
    assert np.array_equal(got > 0 if dtype == "uint16" else np.isfinite(got), valid)
    want = data[valid].astype(np.float64)
    error = np.abs(got[valid].astype(np.float64) - want)
    assert np.all(error <= np.maximum(max_error, 0.005 * want))
    assert error.max() > 0  # lossy, within the bound
    lossless = depth_array(zarr, zarr.storage.MemoryStore(), data, serializer("depthac"))
    assert _chunk_bytes(array) < _chunk_bytes(lossless)


def _chunk_bytes(array: Any) -> int:
    """The bytes of an array's chunks in its memory store (its metadata left out)."""
    items = array.store._store_dict.items()
    return sum(len(v.to_bytes()) for k, v in items if not k.endswith(("zarr.json", ".zarray")))


def test_zarr_partial_edge_chunks_work() -> None:
    """Chunks of part of a frame are images too; Zarr pads those at the edge with the fill."""
    zarr = _zarr()
    from pcdcodec.zarr import serializer

    data = frames("sample", "uint16", 2)
    array = depth_array(zarr, zarr.storage.MemoryStore(), data, serializer(), chunks=(1, 200, 300))
    assert array.nchunks == 2 * 3 * 3
    assert_bit_exact(zarr.open_array(array.store)[:], data)
    assert_bit_exact(array[1, 100:300, 250:400], data[1, 100:300, 250:400])


def test_zarr_refuses_chunks_of_several_frames_and_other_dtypes() -> None:
    zarr = _zarr()
    from pcdcodec.zarr import serializer

    store = zarr.storage.MemoryStore()
    kw: dict[str, Any] = {"shape": (4, 48, 64), "compressors": None}
    with pytest.raises(pcdcodec.InputError, match=r"chunk shape \(2, 48, 64\).*chunks=\(1, H, W\)"):
        zarr.create_array(store, chunks=(2, 48, 64), dtype="uint16", serializer=serializer(), **kw)
    with pytest.raises(pcdcodec.InputTypeError, match="uint16 or float32, got int32"):
        zarr.create_array(store, chunks=(1, 48, 64), dtype="int32", serializer=serializer(), **kw)
    png = serializer("png16")
    if "float32" not in png.codec.dtypes:
        with pytest.raises(pcdcodec.InputTypeError, match=r"png16 takes arrays of uint16"):
            zarr.create_array(store, chunks=(1, 48, 64), dtype="float32", serializer=png, **kw)
    with pytest.raises(pcdcodec.UnknownCodecError):
        serializer("h264")
    with pytest.raises(pcdcodec.InputError, match="not both"):
        serializer("depthac:max_error=1", max_rel_error=0.01)


def test_zarr_serializer_accepts_every_way_of_naming_a_codec() -> None:
    _zarr()
    from pcdcodec.zarr import serializer

    want = serializer("depthac", max_rel_error=0.01)
    assert serializer("pcdcodec.depthac", max_rel_error=0.01) == want
    assert serializer("depthac:max_rel_error=0.01") == want
    assert serializer({"id": "depthac", "max_rel_error": 0.01}) == want
    assert serializer(pcdcodec.get_codec("depthac", max_rel_error=0.01)) == want
    assert want.to_dict() == {"name": "pcdcodec.depthac", "configuration": {"max_rel_error": 0.01}}


def test_zarr_v2_array_takes_the_numcodec_as_compressor() -> None:
    zarr = _zarr()
    data = frames("sample", "uint16", 3)
    store = zarr.storage.MemoryStore()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Zarr warns that v2 arrays are not the newest format
        array = zarr.create_array(
            store,
            shape=data.shape,
            chunks=(1, *data.shape[1:]),
            dtype=data.dtype,
            zarr_format=2,
            filters=None,
            compressors=pz_numcodecs.numcodec("depthac", max_rel_error=0.0),
        )
        array[:] = data
        reopened = zarr.open_array(store)
    assert reopened.metadata.to_dict()["compressor"] == {
        "id": "pcdcodec.depthac",
        "max_rel_error": 0.0,
    }
    assert_bit_exact(reopened[:], data)


def test_docs_example_runs(tmp_path: Path) -> None:
    """The example of docs/zarr.md, and its numcodecs one, run as written."""
    _zarr()
    text = (REPO / "docs" / "zarr.md").read_text()
    blocks = [b.split("```", 1)[0] for b in text.split("```python\n")[1:]]
    assert len(blocks) >= 3
    script = (
        blocks[0] + blocks[-1] + "\nassert (zarr.open_array('depth_v2.zarr')[:] == depth).all()\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script],
        env={"PYTHONPATH": f"{entry_point_path(tmp_path)}:{REPO}", "PATH": ""},
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    assert "'name': 'pcdcodec.depthac'" in out.stdout
    assert (tmp_path / "depth.zarr" / "zarr.json").is_file()


def test_zarr_shards_hold_several_depth_frames() -> None:
    """With sharding, each frame is still one chunk, and one file holds several."""
    zarr = _zarr()
    from pcdcodec.zarr import serializer

    data = frames("sample", "uint16", 6)
    shards = (3, *data.shape[1:])
    array = depth_array(zarr, zarr.storage.MemoryStore(), data, serializer(), shards=shards)
    inner = array.metadata.to_dict()["codecs"][0]["configuration"]["codecs"]
    assert inner == ({"name": "pcdcodec.depthac", "configuration": {}},)
    assert len([k for k in array.store._store_dict if k.startswith("c/")]) == 2
    reopened = zarr.open_array(array.store)
    assert_bit_exact(reopened[:], data)
    assert_bit_exact(reopened[4], data[4])


def test_pcdcodec_imports_neither_numcodecs_nor_zarr() -> None:
    script = (
        "import sys, pcdcodec, pcdcodec.zarr\n"
        "pcdcodec.list_codecs()\n"
        "print(','.join(m for m in ('numcodecs', 'zarr', 'pcdcodec.zarr.v3',"
        " 'pcdcodec.zarr.numcodecs') if m in sys.modules))\n"
        "pcdcodec.zarr.numcodec('depthac')\n"
        "print('zarr' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script],
        env={"PYTHONPATH": str(REPO), "PATH": ""},
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.split() == ["False"]  # nothing listed; numcodecs alone loads no zarr


def _v2_array(zarr: Any, where: Path, dtype: str, codec: Any) -> Any:
    """A Zarr format 2 array of two 48x64 frames in a folder, ``codec`` its compressor."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Zarr warns that v2 arrays are not the newest format
        return zarr.create_array(
            zarr.storage.LocalStore(where),
            shape=(2, 48, 64),
            chunks=(1, 48, 64),
            dtype=dtype,
            zarr_format=2,
            filters=None,
            compressors=codec,
            fill_value=0,
        )


@pytest.mark.parametrize("name", DEPTH_CODECS)
def test_zarr_v2_chunk_of_another_shape_or_dtype_is_a_decode_error(
    name: str, tmp_path: Path
) -> None:
    zarr = _zarr()
    codec = pz_numcodecs.numcodec(name)
    tall = (np.arange(64 * 48, dtype=np.uint16).reshape(64, 48) % 700) * 3
    images = {"uint16": tall, "float32": tall.astype(np.float32) / 1000}
    for array_dtype in ("uint16", "float32"):
        where = tmp_path / array_dtype
        array = _v2_array(zarr, where, array_dtype, codec)
        for image_dtype in _dtypes(name):
            image = images[image_dtype]
            for shape in ((64, 48), (48, 64)):
                right = shape == (48, 64) and image_dtype == array_dtype
                frame = np.ascontiguousarray(image.reshape(shape))
                (where / "0.0.0").write_bytes(codec.codec.encode(frame))
                if right:
                    assert_bit_exact(array[0], frame)
                    continue
                with pytest.raises(pcdcodec.DecodeError, match="chunk does not fit the array"):
                    array[0]
                # Zarr format 2 with zarr-python 2 decodes a whole chunk into the array itself.
                if frame.nbytes == 48 * 64 * np.dtype(array_dtype).itemsize:
                    out = np.zeros((1, 48, 64), array_dtype)
                    why = r"not this array's chunk|out is"
                    with pytest.raises(pcdcodec.PcdcodecError, match=why):
                        codec.decode(codec.codec.encode(frame), out=out)


def test_numcodec_decoded_image_is_an_array_that_refuses_only_other_images() -> None:
    codec = pz_numcodecs.numcodec("rvl")
    depth = load_depths("sample", 1)[0]
    image = codec.decode(codec.encode(depth))
    assert isinstance(image, np.ndarray)
    assert np.array_equal(image.reshape(1, *depth.shape)[0], depth)
    assert type(image.reshape(1, *depth.shape)) is np.ndarray
    assert np.array_equal(image.reshape(-1), depth.reshape(-1))
    assert image.astype(np.float32).reshape(depth.shape[::-1]).shape == depth.shape[::-1]
    assert np.asarray(image).reshape(depth.shape[::-1]).shape == depth.shape[::-1]
    with pytest.raises(pcdcodec.DecodeError, match=r"holds a 480x640 depth image.*640x480"):
        image.reshape(-1).reshape(depth.shape[::-1])
    with pytest.raises(pcdcodec.DecodeError, match="a uint16 depth image, the array is int16"):
        image.view(np.int16).reshape(1, *depth.shape)
    with pytest.raises(pcdcodec.DecodeError, match="byte-swapped"):
        image.view(">u2").reshape(depth.shape)
    with pytest.raises(pcdcodec.DecodeError, match="order 'F'"):
        image.reshape(depth.shape, order="F")
