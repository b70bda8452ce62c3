import numpy as np, pcdcodec
from pcdcodec.zarr import numcodec
d = pcdcodec.load_sample()[0].depth
f = (d / np.float32(1000)).astype(np.float32); f[f == 0] = np.nan
bits = f.view(np.uint32)
bits[0, :6] = [0x7fc00001, 0xffc00000, 0x80000000, 0x00000001, 0x7f800000, 0xff800000]
bits[1, :3] = [0x7fa00000, 0x7f800001, 0xffffffff]  # signalling NaN, max payload
for name in ("depthac", "jpegxl", "zstd", "lz4"):
    c = numcodec(name)
    back = c.decode(c.encode(f))
    print(name, "bit exact:", back.view(np.uint32).tobytes() == f.view(np.uint32).tobytes())
