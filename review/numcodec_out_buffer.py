"""pcdcodec's numcodecs codecs, decode(out=...): an out of the wrong size or dtype raises numpy's
ValueError (not a PcdcodecError), and a big-endian out gets the image's bytes reinterpreted."""
import numpy as np, pcdcodec
from pcdcodec.zarr import numcodec
d = pcdcodec.load_sample()[0].depth
c = numcodec("depthac")
enc = c.encode(d)
for label, out in (("(10, 10) uint16", np.empty((10, 10), np.uint16)),
                   ("(480, 640) float32", np.empty(d.shape, np.float32)),
                   ("(480, 640) >u2", np.empty(d.shape, ">u2"))):
    try:
        c.decode(enc, out=out)
        print(f"out {label}: no error; equal to the depth: {np.array_equal(out, d)}")
    except Exception as e:
        print(f"out {label}: {type(e).__name__}: {e} | a PcdcodecError: {isinstance(e, pcdcodec.PcdcodecError)}")
for label, buf in (("a str", "abc"), ("a strided array", np.frombuffer(enc, np.uint8)[::2])):
    try:
        c.decode(buf)
    except Exception as e:
        print(f"decode({label}): {type(e).__name__}: {e} | a PcdcodecError: {isinstance(e, pcdcodec.PcdcodecError)}")
