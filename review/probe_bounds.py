import numpy as np, pcdcodec
from pcdcodec.zarr import numcodec
d = pcdcodec.load_sample()[0].depth
f = (d / np.float32(1000)).astype(np.float32); f[f == 0] = np.nan; f[0,0]=np.inf; f[0,1] = 3e38
for kw in ({"max_error": 1e30}, {"max_error": 1e-30}, {"max_rel_error": 0.99}, {"max_rel_error": 1e-12}, {"max_error": 65535}, {"max_error": 0.5}):
    for img in (d, f):
        try:
            c = numcodec("depthac", **kw)
            back = c.decode(c.encode(img))
            valid = np.isfinite(img) & (img > 0)
            bound = np.maximum(kw.get("max_error", 0), kw.get("max_rel_error", 0) * np.where(valid, img, 0).astype(np.float64))
            err = np.abs(back.astype(np.float64) - img.astype(np.float64))
            print(kw, img.dtype, "within bound:", bool(np.all(err[valid] <= bound[valid] * (1 + 1e-6) + 1e-12)), "holes kept:", bool(np.array_equal(~valid, ~(np.isfinite(back) & (back > 0)))), "inf kept", back.ravel()[0] if img.dtype == np.float32 else "")
        except pcdcodec.PcdcodecError as e:
            print(kw, img.dtype, "PCD", type(e).__name__, e)
        except Exception as e:
            print(kw, img.dtype, "FOREIGN", type(e).__name__, e)
