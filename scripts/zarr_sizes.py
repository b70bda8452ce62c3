"""The size of a Zarr depth array of each sequence, with pcdcodec's codecs and with the usual ones.

Each sequence present (the real ones in ``../shared/data`` and the bundled sample) becomes a
T×H×W array, one frame per chunk, stored on disk once per codec; the table gives the bytes on
disk (chunks and metadata) and the ratio against the raw frames. Every array is read back and
checked bit-exact. Columns:

* ``pcdcodec.depthac`` (and ``pcdcodec.jpegxl``, ``pcdcodec.png16``): Zarr v3 arrays with the
  depth codec as serializer (:mod:`pcdcodec.zarr`);
* Blosc-zstd: Zarr v3's ``blosc`` codec (numcodecs' Blosc) with zstd, byte shuffle and
  ``--level`` (Zarr's default 5), and at level 9 without shuffle, Blosc's smallest on depth
  (byte and bit shuffle gave larger arrays on the bundled sample); zstd: Zarr v3's ``zstd``
  codec at level 3;
* imagecodecs PNG and JPEG XL: ``imagecodecs.numcodecs``'s ``Png`` (16-bit, its default
  level) and ``Jpegxl`` (lossless, its default effort), numcodecs codecs used as the compressor
  of Zarr v2 arrays, since Zarr v3 has no wrapper for them.

uint16 depth by default, or float32 metres with NaN holes (``--float32``; PNG is left out, as
it holds no float32). Sizes do not depend on the machine.

Run: ``python scripts/zarr_sizes.py [--frames N] [--float32] [--sets tum_fr1_rpy,...]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pcdcodec.bench.sequences import PRESENT, SEQUENCES, load_depths


def _stored_bytes(root: Path) -> int:
    return sum(p.stat().st_size for p in root.rglob("*") if p.is_file())


def _v3(zarr: Any, serializer: Any = "auto", compressors: Any = None) -> Callable[..., Any]:
    def create(store: Path, data: np.ndarray[Any, Any]) -> Any:
        return zarr.create_array(
            zarr.storage.LocalStore(store),
            shape=data.shape,
            chunks=(1, *data.shape[1:]),
            dtype=data.dtype,
            serializer=serializer,
            compressors=compressors,
        )

    return create


def _v2(zarr: Any, compressor: Any) -> Callable[..., Any]:
    def create(store: Path, data: np.ndarray[Any, Any]) -> Any:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # v2 arrays and codecs outside the v3 spec
            return zarr.create_array(
                zarr.storage.LocalStore(store),
                shape=data.shape,
                chunks=(1, *data.shape[1:]),
                dtype=data.dtype,
                zarr_format=2,
                filters=None,
                compressors=compressor,
            )

    return create


def layouts(level: int, float32: bool) -> dict[str, Callable[..., Any]]:
    """Column name -> a function making the empty array in a store folder."""
    import imagecodecs.numcodecs as icn
    import zarr

    from pcdcodec.zarr import serializer

    icn.register_codecs()  # so the arrays' metadata finds them again on reading
    out = {
        "pcdcodec.depthac": _v3(zarr, serializer("depthac")),
        f"Blosc-zstd {level} shuffle": _v3(
            zarr,
            compressors=zarr.codecs.BloscCodec(cname="zstd", clevel=level, shuffle="shuffle"),
        ),
        "Blosc-zstd 9 no shuffle": _v3(
            zarr,
            compressors=zarr.codecs.BloscCodec(cname="zstd", clevel=9, shuffle="noshuffle"),
        ),
        "zstd 3": _v3(zarr, compressors=zarr.codecs.ZstdCodec(level=3)),
        "imagecodecs JPEG XL": _v2(zarr, icn.Jpegxl(lossless=True)),
        "pcdcodec.jpegxl": _v3(zarr, serializer("jpegxl")),
    }
    if not float32:
        out["imagecodecs PNG"] = _v2(zarr, icn.Png())
        out["pcdcodec.png16"] = _v3(zarr, serializer("png16"))
    return out


def measure(data: np.ndarray[Any, Any], make: Callable[..., Any], work: Path) -> int:
    """Bytes on disk of ``data`` in the array ``make`` builds, after checking it reads back."""
    store = work / "array.zarr"
    array = make(store, data)
    array[:] = data
    import zarr

    back = zarr.open_array(zarr.storage.LocalStore(store, read_only=True))[:]
    view = np.uint32 if data.dtype.itemsize == 4 else np.uint16
    if back.dtype != data.dtype or not np.array_equal(back.view(view), data.view(view)):
        raise SystemExit(f"{store}: the array did not read back bit-exact")
    size = _stored_bytes(store)
    for p in sorted(store.rglob("*"), reverse=True):
        p.unlink() if p.is_file() else p.rmdir()
    store.rmdir()
    return size


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000, help="frames per sequence, at most")
    parser.add_argument("--level", type=int, default=5, help="Blosc's clevel")
    parser.add_argument("--float32", action="store_true", help="float32 metres, NaN holes")
    parser.add_argument("--sets", default=",".join(PRESENT), help="comma-separated sequences")
    args = parser.parse_args()
    names = [n for n in args.sets.split(",") if n]
    columns = layouts(args.level, args.float32)
    rows: dict[str, dict[str, tuple[int, float]]] = {}
    header: dict[str, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            depths = np.stack(load_depths(name, args.frames))
            if args.float32:
                metres = (depths / SEQUENCES[name].depth_scale).astype(np.float32)
                metres[depths == 0] = np.nan
                data: np.ndarray[Any, Any] = metres
            else:
                data = depths
            t, h, w = data.shape
            label = "sample (bundled)" if name == "sample" else name
            header[name] = f"{label} ({t} × {w}×{h}, {data.nbytes / 1e6:.1f} MB raw)"
            for column, make in columns.items():
                size = measure(data, make, Path(tmp))
                rows.setdefault(column, {})[name] = (size, data.nbytes / size)
                print(f"{name}: {column}: {size} bytes, {data.nbytes / size:.2f}x", file=sys.stderr)
    kind = "float32 metres" if args.float32 else "uint16"
    print(f"\nZarr {kind} depth arrays, one frame per chunk: MB on disk (ratio to raw)\n")
    print("| codec | " + " | ".join(header[n] for n in names) + " | ratio range |")
    print("|---" * (len(names) + 2) + "|")
    for column, by_set in rows.items():
        cells = [f"{by_set[n][0] / 1e6:.2f} ({by_set[n][1]:.2f}×)" for n in names]
        ratios = [by_set[n][1] for n in names]
        print(f"| {column} | " + " | ".join(cells) + f" | {min(ratios):.2f}–{max(ratios):.2f}× |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
