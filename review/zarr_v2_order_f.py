"""A Zarr format 2 array of order 'F' with a pcdcodec numcodec as its compressor reads back
scrambled: the codec codes the logical image and returns it C-ordered, while Zarr v2 takes the
decoded buffer's bytes as the chunk in Fortran order."""
import warnings, numpy as np, zarr, pcdcodec
from pcdcodec.zarr import numcodec
d = np.stack(pcdcodec.load_sample().depths[:2])
warnings.simplefilter("ignore")
for order in ("C", "F"):
    a = zarr.create_array(zarr.storage.MemoryStore(), shape=d.shape, chunks=(1, *d.shape[1:]), dtype="<u2",
                          order=order, zarr_format=2, filters=None, compressors=numcodec("depthac"))
    try:
        a[:] = d
        print(f"order {order}: read back equal: {np.array_equal(a[:], d)}")
    except Exception as e:
        print(f"order {order}: {type(e).__name__}: {e}")
