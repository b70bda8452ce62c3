"""Write golden bounded-error (lossy) depth frames for configs that have none yet.

The crops are those of ``make_golden.py``; each config's frames are encoded once and committed
with the config and a SHA-256 of what they decode to. ``tests/test_error_bound.py`` decodes them
on every run, so a change of the lossy layout or of the level tables fails a test. Existing
goldens are never rewritten. Run: ``python tests/golden/make_bounded_golden.py``.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from tests.golden.make_golden import CROPS, golden_source  # noqa: E402

#: (file stem, codec config, near-lossless tolerance the frames are coded with).
CONFIGS: list[tuple[str, dict[str, Any], int]] = [
    ("depthac-rel1", {"id": "depthac", "max_rel_error": 0.01}, 0),
    ("depthac-abs-rel", {"id": "depthac", "max_error": 0.004, "max_rel_error": 0.005}, 0),
    ("depthac-rel1-near2", {"id": "depthac", "max_rel_error": 0.01}, 2),
    ("zstd-rel05", {"id": "zstd", "max_rel_error": 0.005}, 0),
    # uint16 frames since levels are fitted to each frame (kind 3); float32 as above.
    ("depthac-rel05-fitted", {"id": "depthac", "max_rel_error": 0.005}, 0),
    ("jpegxl-abs-fitted", {"id": "jpegxl", "max_error": 0.006}, 0),
    # float32 too since its levels are fitted to each frame (kind 4).
    ("depthac-rel1-fitted", {"id": "depthac", "max_rel_error": 0.01}, 0),
]


def digest(array: Any) -> str:
    return hashlib.sha256(array.tobytes()).hexdigest()


def main() -> int:
    import pcdcodec
    from pcdcodec.depth import FrameCodec

    folder = HERE / "depth_bounded"
    folder.mkdir(exist_ok=True)
    for stem, config, near in CONFIGS:
        index_path = folder / f"{stem}.json"
        if index_path.exists():
            continue
        codec = pcdcodec.get_codec(config)
        assert isinstance(codec, FrameCodec)
        type(codec).bounded_near, saved = near, type(codec).bounded_near
        try:
            entries = []
            for i, (source, rows, cols) in enumerate(CROPS):
                for dtype in codec.dtypes:
                    entry = {"source": source, "rows": rows, "cols": cols, "dtype": dtype}
                    data = codec.encode(golden_source(entry))
                    file = f"{stem}-{i}-{dtype}.bin"
                    (folder / file).write_bytes(data)
                    decoded = codec.decode(data)
                    entries.append({**entry, "file": file, "decoded_sha256": digest(decoded)})
        finally:
            type(codec).bounded_near = saved
        index = {
            "config": config,
            "near": near,
            "version": pcdcodec.__version__,
            "frames": entries,
        }
        index_path.write_text(json.dumps(index, indent=2) + "\n")
        print(f"wrote {len(entries)} golden frames for {stem}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
