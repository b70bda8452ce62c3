"""Write golden depth frames for codecs that have none yet.

Each golden is a crop of a bundled sample frame, encoded once and committed with the codec's
config. ``tests/test_golden.py`` decodes them on every run, so a change of the on-disk format
fails a test. Existing goldens are never rewritten: a format change needs a new format version,
not new goldens. Run: ``python tests/golden/make_golden.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
SAMPLE = HERE.parents[1] / "pcdcodec" / "data" / "tum_fr1_rpy"

#: (sample depth file, row slice, column slice): a crop with holes, edges and a smooth wall.
CROPS = [
    ("depth/1305031229.528784.png", (180, 244), (280, 376)),
    ("depth/1305031229.997931.png", (0, 48), (560, 640)),
]
DEPTH_SCALE = 5000.0


def golden_source(entry: dict[str, Any]) -> np.ndarray[Any, Any]:
    """The array a golden entry must decode to, rebuilt from the bundled sample."""
    import imagecodecs

    depth = np.asarray(imagecodecs.png_decode((SAMPLE / entry["source"]).read_bytes()))
    (r0, r1), (c0, c1) = entry["rows"], entry["cols"]
    crop = np.ascontiguousarray(depth[r0:r1, c0:c1])
    if entry["dtype"] == "uint16":
        return crop
    metres = (crop / DEPTH_SCALE).astype(np.float32)
    metres[crop == 0] = np.nan
    return metres


def main() -> int:
    import pcdcodec
    from pcdcodec.depth import FrameCodec

    folder = HERE / "depth"
    folder.mkdir(exist_ok=True)
    for name in pcdcodec.list_codecs("depth"):
        index_path = folder / f"{name}.json"
        if index_path.exists():
            continue
        codec = pcdcodec.get_codec(name)
        assert isinstance(codec, FrameCodec)
        entries = []
        for i, (source, rows, cols) in enumerate(CROPS):
            for dtype in codec.dtypes:
                entry = {"source": source, "rows": rows, "cols": cols, "dtype": dtype}
                data = codec.encode(golden_source(entry))
                file = f"{name}-{i}-{dtype}.bin"
                (folder / file).write_bytes(data)
                entries.append({**entry, "file": file})
        index = {"config": codec.get_config(), "version": pcdcodec.__version__, "frames": entries}
        index_path.write_text(json.dumps(index, indent=2) + "\n")
        print(f"wrote {len(entries)} golden frames for {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
