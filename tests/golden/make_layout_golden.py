"""Write the container-layout goldens: a tiny recording and its paper-layout export, as this
version of pcdcodec writes them.

``tests/test_container_golden.py`` reads them on every run and compares a fresh write's
container structure (records, channels, metadata keys, stored codec configs) with the newest
(``SEALED``: with color digests and a seal), so a change of the on-disk layout fails a test
instead of slipping through unnoticed. Existing goldens are never rewritten: a deliberate
change adds new ones beside them (``RECORDING`` is the layout before color digests).
Run: ``python tests/golden/make_layout_golden.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RECORDING = HERE / "recording" / "layout-ffv1-zstd.pcdc"
SEALED = HERE / "recording" / "layout-sealed-ffv1-zstd.pcdc"
PAPER = HERE / "paper" / "layout-ffv1"


def write_recording(path: Path) -> None:
    import pcdcodec

    from .make_recording_golden import HEIGHT, WIDTH, golden_frames

    cam = pcdcodec.CameraIntrinsics(WIDTH, HEIGHT, 52.5, 52.5, 31.5, 23.5)
    with pcdcodec.open(
        path,
        "w",
        intrinsics=cam,
        depth_scale=5000.0,
        color="ffv1",
        depth="zstd",
        metadata={"site": "lab"},
        overwrite=True,
    ) as rec:
        for color, depth, ts in golden_frames():
            rec.write(color, depth, ts)


def main() -> int:
    from pcdcodec.convert.paper import export_paper

    if SEALED.exists():
        print(f"{SEALED} exists; goldens are never rewritten")
        return 1
    write_recording(SEALED)
    print(f"wrote {SEALED}")
    if not PAPER.exists():
        export_paper(SEALED, PAPER)
        print(f"wrote {PAPER}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parents[1]))
    from tests.golden import make_layout_golden

    sys.exit(make_layout_golden.main())
