"""The size of the ``.rrd`` file ``pcdcodec view --save`` writes, against the ``.pcdc`` it shows.

For each set present (the bundled sample and the dense sequences of ``../shared/data``) it
writes the first ``--frames`` frames with the default codecs (H.264 color, ``depthac`` depth;
poses where the set has them), then saves the recording as a Rerun file in each way:

* ``before``: what ``view`` logged by default before it kept files small: raw depth pixels
  (``DepthImage``), color decoded and logged as JPEG (quality 90) and the point cloud of every
  2nd pixel (``depth_format="raw", video=False, points=True``; the trajectory is logged once
  here, where it was logged whole at every frame, a few kB for these lengths);
* ``png`` (the default now): depth as lossless 16-bit PNG in ``EncodedDepthImage``, the color
  stream's own H.264 packets in a ``VideoStream``, no point cloud;
* ``rvl``: the same with RVL depth;
* ``png+points``: the default with ``--points``.

Each column gives the ``.rrd`` bytes and their ratio to the ``.pcdc``; the seconds each took
to write are printed as well (they depend on the machine and its load). Every depth image of
the ``png`` and ``rvl`` files is read back with Rerun's reader and checked bit-exact.

Run: ``python scripts/rrd_sizes.py [--frames 50] [--sets sample,tum_fr1_rpy,...]``.
"""

from __future__ import annotations

import argparse
import struct
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import PRESENT, SEQUENCES
from pcdcodec.datasets import load_folder, load_sample
from pcdcodec.depth.rvl import rvl_decode
from pcdcodec.viewer import view

#: Column name -> the options of :func:`pcdcodec.viewer.view`.
WAYS: dict[str, dict[str, Any]] = {
    "before": {"depth_format": "raw", "video": False, "points": True},
    "png": {},
    "rvl": {"depth_format": "rvl"},
    "png+points": {"points": True},
}


def write_recording(name: str, frames: int, path: Path) -> None:
    """The first ``frames`` frames of set ``name`` as a ``.pcdc`` with the default codecs."""
    if name == "sample":
        seq = load_sample(max_frames=frames)
    else:
        spec = SEQUENCES[name]
        seq = load_folder(spec.root, max_frames=frames, **spec.reader_options())
    with pcdcodec.open(
        path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, overwrite=True
    ) as writer:
        writer.write_frames(seq)


def logged_depths(rrd: Path) -> list[np.ndarray[Any, Any]]:
    """Every encoded depth image of ``rrd`` in frame order, read with Rerun's reader."""
    import imagecodecs
    from rerun.chunk import RrdReader

    found: dict[int, np.ndarray[Any, Any]] = {}
    for chunk in RrdReader(rrd).stream():
        batch = chunk.to_record_batch()
        if "EncodedDepthImage:blob" not in batch.schema.names:
            continue
        blobs = batch.column("EncodedDepthImage:blob")
        media = batch.column("EncodedDepthImage:media_type").to_pylist()
        for row, number in enumerate(batch.column("frame").to_pylist()):
            blob = bytes(blobs[row].values[0].values.to_numpy())
            if media[row][0] == "image/png":
                found[number] = imagecodecs.png_decode(blob)
            else:
                width, height = struct.unpack_from("<II", blob, 12)
                image = rvl_decode(memoryview(blob[20:]), width * height)
                found[number] = image.reshape(height, width)
    return [found[k] for k in sorted(found)]


def measure(name: str, frames: int, folder: Path) -> dict[str, Any]:
    """Bytes of the ``.pcdc`` and of each way's ``.rrd``, and the seconds each took."""
    pcdc = folder / f"{name}.pcdc"
    write_recording(name, frames, pcdc)
    with pcdcodec.open(pcdc) as rec:
        depths = [rec.depth(i) for i in range(len(rec))]
    row: dict[str, Any] = {"set": name, "frames": len(depths), "pcdc": pcdc.stat().st_size}
    for way, options in WAYS.items():
        rrd = folder / f"{name}-{way}.rrd"
        start = time.perf_counter()
        view(pcdc, save=rrd, **options)
        row[f"{way} s"] = time.perf_counter() - start
        row[way] = rrd.stat().st_size
        if way in ("png", "rvl"):
            back = logged_depths(rrd)
            if len(back) != len(depths) or not all(
                np.array_equal(a, b) for a, b in zip(back, depths, strict=True)
            ):
                raise SystemExit(f"{name}: the {way} .rrd does not hold the recording's depth")
        rrd.unlink()
    return row


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=50)
    parser.add_argument("--sets", help="comma-separated set names (default: every one present)")
    args = parser.parse_args(argv)
    names = args.sets.split(",") if args.sets else PRESENT
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            rows.append(measure(name, args.frames, Path(tmp)))
    head = f"{'set':20} {'frames':>6} {'.pcdc':>10}"
    print(head + "".join(f" {way:>20}" for way in WAYS))
    for r in rows:
        cells = "".join(
            f" {r[way] / 1e6:9.2f} MB {r[way] / r['pcdc']:5.1f}x {r[f'{way} s']:4.1f}s"
            for way in WAYS
        )
        print(f"{r['set']:20} {r['frames']:6d} {r['pcdc'] / 1e6:7.2f} MB{cells}")
    for way in WAYS:
        ratios = [r[way] / r["pcdc"] for r in rows]
        print(f"{way}: {min(ratios):.1f}x to {max(ratios):.1f}x the .pcdc")
    return rows


if __name__ == "__main__":
    main()
