"""Write golden color streams for stream codecs that have none yet.

Three 64×48 crops of bundled sample frames are encoded once per codec; the packets, their
timestamps and keyframe flags and the codec's config are committed. ``tests/test_golden.py``
decodes them on every run: lossless codecs must give the crops back exactly, and codecs whose
decoding the standard defines bit for bit (H.264, H.265, VP9, AV1) must give back the frames
recorded here, so a change of the stored bitstream or of decoding fails a test.
Run: ``python tests/golden/make_color_golden.py``.
"""

from __future__ import annotations

import base64
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
SAMPLE = HERE.parents[1] / "pcdcodec" / "data" / "tum_fr1_rpy"
#: Codecs whose decoder output is defined exactly by their standard.
EXACT_DECODERS = {"h264", "h265", "vp9", "av1"}


def golden_frames() -> list[np.ndarray[Any, Any]]:
    import imagecodecs

    files = sorted((SAMPLE / "rgb").glob("*.png"))[:3]
    frames = [np.asarray(imagecodecs.png_decode(f.read_bytes())) for f in files]
    return [np.ascontiguousarray(f[200:248, 300:364]) for f in frames]


def digest(frames: list[np.ndarray[Any, Any]]) -> str:
    h = hashlib.sha256()
    for f in frames:
        h.update(f.tobytes())
    return h.hexdigest()


def main() -> int:
    import pcdcodec
    from pcdcodec.color import StreamCodec, decode_packets, encode_frames

    folder = HERE / "color"
    folder.mkdir(exist_ok=True)
    frames = golden_frames()
    for name in pcdcodec.list_codecs("color", available_only=True):
        path = folder / f"{name}.json"
        codec = pcdcodec.get_codec(name)
        if path.exists() or not isinstance(codec, StreamCodec) or name.endswith("nvenc"):
            continue
        packets, extradata = encode_frames(codec, frames, [0, 33_000_000, 66_000_000])
        decoded = decode_packets(codec, packets, 64, 48, extradata)
        entry = {
            "config": codec.get_config(),
            "version": pcdcodec.__version__,
            "width": 64,
            "height": 48,
            "extradata": base64.b64encode(extradata).decode() if extradata else None,
            "packets": [
                {
                    "data": base64.b64encode(p.data).decode(),
                    "pts": p.pts,
                    "dts": p.dts,
                    "keyframe": p.keyframe,
                }
                for p in packets
            ],
            "decoded_sha256": digest([f.rgb for f in decoded]) if name in EXACT_DECODERS else None,
        }
        path.write_text(json.dumps(entry, indent=1) + "\n")
        print(f"wrote golden packets for {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
