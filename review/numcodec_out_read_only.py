"""decode(out=) into a read-only buffer (bytes, or an array made read-only) raises numpy's
ValueError, not a PcdcodecError."""
import numpy as np, pcdcodec
from pcdcodec.zarr import numcodec
d = pcdcodec.load_sample()[0].depth
c = numcodec("depthac")
enc = c.encode(d)
ro = np.zeros(d.shape, np.uint16)
ro.flags.writeable = False
for label, out in (("bytes", bytes(d.nbytes)), ("read-only array", ro)):
    try:
        c.decode(enc, out=out)
        print(label, "no error")
    except Exception as e:
        print(f"{label}: {type(e).__name__}: {e} | a PcdcodecError: {isinstance(e, pcdcodec.PcdcodecError)}")
