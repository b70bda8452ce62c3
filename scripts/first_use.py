"""The first frame after a fresh install: depth codecs' encode and decode with an empty numba cache.

Each codec runs in a fresh process whose ``NUMBA_CACHE_DIR`` is an empty folder, so what numba
compiles on first use is timed as a new user meets it; a second process on the same folder
shows the warm cache. Prints one row per codec: cold encode, cold decode, warm encode, warm decode
(seconds, the first call each; CPU seconds in brackets), cold decode in a process that only
decodes, and the numba functions compiled with how many type
specialisations each (every one costs compile time).

Run: ``python scripts/first_use.py [--codec depthac] [--repeat 3]`` (the cold figures vary with
the machine's load: take the range over repeats).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

import pcdcodec

REPO = Path(__file__).resolve().parents[1]

# Wall time, and the process's CPU time: on a busy machine the wall time also counts the
# waits for a core, while the CPU time is what the same work takes on a quiet one.
_CHILD = """
import json, sys, time
import pcdcodec
depth = pcdcodec.load_sample(max_frames=1)[0].depth
codec = pcdcodec.get_codec({codec!r})
data = open(sys.argv[1], "rb").read() if len(sys.argv) > 1 else None
clocks = (time.perf_counter, time.process_time)
t0 = [c() for c in clocks]
if data is None:
    data = codec.encode(depth)
t1 = [c() for c in clocks]
back = codec.decode(data)
t2 = [c() for c in clocks]
assert (back == depth).all()
print(json.dumps({{"encode": t1[0] - t0[0], "decode": t2[0] - t1[0],
                   "encode_cpu": t1[1] - t0[1], "decode_cpu": t2[1] - t1[1]}}))
"""


def _run(codec: str, cache: Path, encoded: Path | None = None) -> dict[str, float]:
    """One fresh process: encode the sample's first frame and decode it, or with ``encoded``
    decode that file only (what a user who only reads recordings meets)."""
    env = {"NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(REPO)}
    extra = [str(encoded)] if encoded is not None else []
    out = subprocess.run(
        [sys.executable, "-c", _CHILD.format(codec=codec), *extra],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, **env},
    ).stdout
    result: dict[str, float] = json.loads(out.strip().splitlines()[-1])
    return result


def _specialisations(cache: Path) -> Counter[str]:
    """Compiled functions in a numba cache folder, and how many type signatures each has."""
    found: Counter[str] = Counter()
    for path in cache.rglob("*.nbc"):
        # "<module>.<function>-<line>.py311.<n>.nbc": one file per compiled signature
        found[path.name.split("-")[0]] += 1
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--codec", action="append", help="depth codec (default: depthac)")
    parser.add_argument("--repeat", type=int, default=1, help="cold runs per codec")
    args = parser.parse_args(argv)
    print(
        "| codec | cold encode s (CPU s) | cold decode s (CPU s) | cold decode only s (CPU s) "
        "| warm encode s | warm decode s |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    compiled: Counter[str] = Counter()
    for codec in args.codec or ["depthac"]:
        encoded = pcdcodec.get_codec(codec).encode(pcdcodec.load_sample(max_frames=1)[0].depth)
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                cache = Path(tmp) / "both"
                cold = _run(codec, cache)
                warm = _run(codec, cache)
                compiled = _specialisations(cache)
                frame = Path(tmp) / "frame.bin"
                frame.write_bytes(encoded)
                alone = _run(codec, Path(tmp) / "decode", frame)
            print(
                f"| {codec} | {cold['encode']:.2f} ({cold['encode_cpu']:.2f}) "
                f"| {cold['decode']:.2f} ({cold['decode_cpu']:.2f}) "
                f"| {alone['decode']:.2f} ({alone['decode_cpu']:.2f}) "
                f"| {warm['encode']:.2f} | {warm['decode']:.2f} |"
            )
    if compiled:
        print(
            "\ncompiled (signatures):", ", ".join(f"{k} ({v})" for k, v in sorted(compiled.items()))
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
