"""Bit flips, truncations and byte changes in every depth codec's frames, decoded through the
numcodecs codec: every outcome must be the image or a PcdcodecError."""
import sys, time, numpy as np, pcdcodec
from pcdcodec.zarr import numcodec
d = pcdcodec.load_sample()[0].depth[:120, :160].copy()
f = (d / np.float32(1000)).astype(np.float32); f[f == 0] = np.nan
rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
tally = {}
for name in pcdcodec.list_codecs("depth"):
    c = numcodec(name)
    for img in ([d, f] if "float32" in c.codec.dtypes else [d]):
        enc = c.encode(img)
        for k in range(300):
            b = bytearray(enc)
            how = k % 4
            if how == 0:
                pos = int(rng.integers(len(b))); b[pos] ^= 1 << int(rng.integers(8))
            elif how == 1:
                b = b[: int(rng.integers(len(b)))]
            elif how == 2:
                for _ in range(4):
                    b[int(rng.integers(len(b)))] = int(rng.integers(256))
            else:
                pos = int(rng.integers(20, len(b))); b[pos:] = rng.bytes(len(b) - pos)
            t0 = time.perf_counter()
            try:
                out = c.decode(bytes(b))
                r = "ok-equal" if out.tobytes() == img.tobytes() else "ok-DIFFERENT"
            except pcdcodec.PcdcodecError:
                r = "PcdcodecError"
            except Exception as e:
                r = f"FOREIGN {type(e).__name__}: {e}"
            dt = time.perf_counter() - t0
            if dt > 2: r += f" SLOW {dt:.1f}s"
            key = (name, str(img.dtype), r)
            tally[key] = tally.get(key, 0) + 1
for k, v in sorted(tally.items()):
    print(v, *k)
