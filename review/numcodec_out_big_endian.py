"""numcodecs decode(out=) with a big-endian out array: are the values right?"""
import numpy as np, pcdcodec
from pcdcodec.zarr import numcodec
d = pcdcodec.load_sample()[0].depth
c = numcodec("depthac")
enc = c.encode(d)
out = np.empty(d.shape, ">u2")
c.decode(enc, out=out)
print("out dtype", out.dtype, "equal to the depth:", np.array_equal(out, d))
print("first nonzero want", d[d > 0][:3], "got", out[d > 0][:3])
# encoding big-endian input
print("big-endian uint16 encode round trip equal:", np.array_equal(c.decode(c.encode(d.astype(">u2"))), d))
f = (d / np.float32(1000)).astype(np.float32)
print("big-endian float32 encode round trip equal:", np.array_equal(c.decode(c.encode(f.astype(">f4"))), f))
