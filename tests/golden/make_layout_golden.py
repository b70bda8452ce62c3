"""Write the container-layout goldens: a tiny recording and its paper-layout export, as this
version of pcdcodec writes them.

``tests/test_container_golden.py`` reads both on every run and compares a fresh write's
container structure (records, channels, metadata keys, stored codec configs) with them, so a
change of the on-disk layout fails a test instead of slipping through under the same format
version. Existing goldens are never rewritten: a deliberate change adds new ones beside them.
Run: ``python tests/golden/make_layout_golden.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RECORDING = HERE / "recording" / "layout-ffv1-zstd.pcdc"
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
    from pcdcodec.recording.paper import export_paper

    if RECORDING.exists() or PAPER.exists():
        print(f"{RECORDING} or {PAPER} exists; goldens are never rewritten")
        return 1
    write_recording(RECORDING)
    export_paper(RECORDING, PAPER)
    print(f"wrote {RECORDING} and {PAPER}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parents[1]))
    from tests.golden import make_layout_golden

    sys.exit(make_layout_golden.main())
