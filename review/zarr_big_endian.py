"""Zarr arrays of big-endian depth with the pcdcodec codecs: do they read back what was written?"""
import tempfile, numpy as np, zarr, pcdcodec
from pcdcodec.zarr import numcodec, serializer
d = np.stack(pcdcodec.load_sample().depths[:3])
tmp = tempfile.mkdtemp()
for dt in (">u2", "<u2"):
    for fmt in (2, 3):
        kw = dict(compressors=numcodec("depthac"), filters=None) if fmt == 2 else dict(serializer=serializer("depthac"), compressors=None)
        try:
            a = zarr.create_array(f"{tmp}/a{fmt}{dt[0]}.zarr", shape=d.shape, chunks=(1, *d.shape[1:]), dtype=dt, zarr_format=fmt, **kw)
            a[:] = d.astype(dt)
            back = zarr.open_array(f"{tmp}/a{fmt}{dt[0]}.zarr", mode="r")[:]
            print(f"zarr v{fmt} dtype {dt}: read back equal: {np.array_equal(back, d)}; sample {d[0][d[0]>0][:2]} -> {back[0][d[0]>0][:2]}")
        except Exception as e:
            print(f"zarr v{fmt} dtype {dt}: {type(e).__name__}: {e}")
