import numpy as np, zarr, pcdcodec
from pcdcodec.zarr import serializer
d = np.stack(pcdcodec.load_sample().depths[:2])
for kw in (dict(order="F"), dict(config={"order": "F"}), dict(filters=[zarr.codecs.TransposeCodec(order=(0, 2, 1))]), dict(filters=[zarr.codecs.TransposeCodec(order=(1, 2, 0))])):
    try:
        a = zarr.create_array(zarr.storage.MemoryStore(), shape=d.shape, chunks=(1, *d.shape[1:]), dtype="<u2", serializer=serializer("depthac"), compressors=None, **kw)
        a[:] = d
        print(kw, "equal:", np.array_equal(a[:], d))
    except Exception as e:
        print(kw, type(e).__name__, e)
