"""Zarr encodes and decodes chunks on several threads at once with one codec instance: are the
arrays still bit-exact?"""
import warnings, numpy as np, zarr, pcdcodec
from pcdcodec.zarr import numcodec, serializer
warnings.simplefilter("ignore")
seq = pcdcodec.load_sample()
base = np.stack(seq.depths)
rng = np.random.default_rng(0)
d = np.concatenate([np.roll(base, int(k), axis=2) for k in rng.integers(0, 640, 4)])  # 60 frames
f = (d / np.float32(5000)).astype(np.float32); f[d == 0] = np.nan
zarr.config.set({"async.concurrency": 32, "threading.max_workers": 16})
for name in pcdcodec.list_codecs("depth"):
    for data in ([d, f] if name in ("depthac", "jpegxl", "zstd", "lz4") else [d]):
        for fmt in (3, 2):
            kw = dict(serializer=serializer(name), compressors=None) if fmt == 3 else dict(compressors=numcodec(name), filters=None)
            a = zarr.create_array(zarr.storage.MemoryStore(), shape=data.shape, chunks=(1, *data.shape[1:]), dtype=data.dtype, zarr_format=fmt, **kw)
            a[:] = data
            ok = all(a[:].view(np.uint8).tobytes() == data.view(np.uint8).tobytes() for _ in range(2))
            print(name, data.dtype, f"v{fmt}", "bit exact:", ok)
