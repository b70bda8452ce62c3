"""Compare codecs on the bundled sample (or a folder or recording given as the argument).

Prints the report of ``pcdcodec.evaluate`` (the four tables of the original method, per codec)
and writes CSV, JSON and PNG plots to ``codec-report/``.

Run: ``python examples/compare_codecs.py [SRC]``.
"""

from __future__ import annotations

import sys

import pcdcodec


def main() -> int:
    source = sys.argv[1] if len(sys.argv) > 1 else pcdcodec.load_sample()
    result = pcdcodec.evaluate(
        source,
        depth=["lz4", "zstd", "jpegxl"],
        color=["h264", "av1", "ffv1"],
        frames=15,
        progress=lambda step: print(f"  {step}", file=sys.stderr),
    )
    print(result.to_markdown())
    written = result.write("codec-report")
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
