"""Time of matching two cameras' frames (``framesets()``) as the recording grows.

Two cameras of N frames each at 30 frames per second, the second 5 ms after the first,
matched with the tolerance of a recording whose stated rate is ``--fps`` (half a frame of it:
at the default 0.01 every frame of one camera is within tolerance of every frame of the other,
the hardest case). Prints each N's time and its ratio to the previous N's: matching in linear
time doubles its time when N doubles.

    python benchmarks/framesets_scaling.py
    python benchmarks/framesets_scaling.py --frames 1000 2000 4000 8000 16000 --fps 30
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
import numpy.typing as npt

from pcdcodec.recording.framesets import framesets


class _Camera:
    def __init__(self, times: npt.NDArray[np.int64], fps: float) -> None:
        self.timestamps = times
        self.fps = fps

    def __getitem__(self, i: Any) -> Any:
        raise NotImplementedError


class _Rig:
    """The two cameras' timestamps, as matching reads a rig recording."""

    def __init__(self, n: int, fps: float) -> None:
        head = np.arange(n, dtype=np.int64) * 33_333_333
        self._cams = {"head": _Camera(head, fps), "wrist": _Camera(head + 5_000_000, fps)}
        self.rig_poses = {name: np.eye(4) for name in self._cams}
        self.camera_names = list(self._cams)

    def frames(self, camera: str | None = None) -> _Camera:
        return self._cams[camera or "head"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[1000, 2000, 4000, 8000])
    parser.add_argument("--fps", type=float, default=0.01, help="the recording's stated rate")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many runs")
    args = parser.parse_args()
    print("| frames per camera | tolerance (s) | seconds | × previous |")
    print("| ---: | ---: | ---: | ---: |")
    last = None
    for n in args.frames:
        rig = _Rig(n, args.fps)
        best = float("inf")
        for _ in range(args.repeat):
            start = time.perf_counter()
            sets = framesets(rig, None, None)
            best = min(best, time.perf_counter() - start)
        assert sets.incomplete == 0, "every set has both cameras"
        ratio = "" if last is None else f"{best / last:.2f}"
        print(f"| {n} | {sets.tolerance_ns / 1e9:g} | {best:.4f} | {ratio} |")
        last = best


if __name__ == "__main__":
    main()
