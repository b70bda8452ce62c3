import numpy as np, traceback, pcdcodec
from pcdcodec.zarr import numcodec
d = pcdcodec.load_sample()[0].depth
def t(label, f):
    try:
        r = f(); print("OK  ", label, getattr(r, "shape", type(r)))
    except pcdcodec.PcdcodecError as e:
        print("PCD ", label, type(e).__name__, e)
    except Exception as e:
        print("FOREIGN", label, type(e).__name__, e)
for name in ["depthac", "rvl", "png16", "zstd", "lz4", "jpegxl"]:
    c = numcodec(name)
    enc = c.encode(d)
    t(f"{name} out wrong size", lambda: c.decode(enc, out=np.empty((10, 10), np.uint16)))
    t(f"{name} out wrong dtype float32", lambda: c.decode(enc, out=np.empty(d.shape, np.float32)))
    t(f"{name} out uint8 bytes", lambda: c.decode(enc, out=np.empty(d.nbytes, np.uint8)))
    t(f"{name} out big-endian", lambda: c.decode(enc, out=np.empty(d.shape, ">u2")))
    t(f"{name} encode big-endian", lambda: c.encode(d.astype(">u2")))
    t(f"{name} encode noncontig", lambda: c.encode(d[:, ::2]))
    t(f"{name} encode empty", lambda: c.encode(np.zeros((0, 0), np.uint16)))
    t(f"{name} encode int32", lambda: c.encode(d.astype(np.int32)))
    t(f"{name} encode bytes", lambda: c.encode(d.tobytes()))
    t(f"{name} decode random", lambda: c.decode(np.random.default_rng(0).bytes(1000)))
    t(f"{name} decode empty", lambda: c.decode(b""))
    t(f"{name} decode str", lambda: c.decode("abc"))
    t(f"{name} decode noncontig", lambda: c.decode(np.frombuffer(enc, np.uint8)[::2]))
    other = numcodec("zstd" if name != "zstd" else "lz4").encode(d)
    t(f"{name} decode foreign codec bytes", lambda: c.decode(other))
    f = d.astype(np.float32) / 1000; f[0, 0] = np.nan; f[0, 1] = np.inf; f[0, 2] = -np.inf
    def rt():
        e = c.encode(f); back = c.decode(e)
        assert back.view(np.uint32).tobytes() == f.view(np.uint32).tobytes(), "not bit exact"
        return back
    t(f"{name} float32 nan/inf roundtrip", rt)
    t(f"{name} float32 big-endian", lambda: c.decode(c.encode(f.astype(">f4"))))
import numcodecs
for cfg in [{"id": "pcdcodec.depthac", "bogus": 1}, {"id": "pcdcodec.depthac", "max_error": "x"},
            {"id": "pcdcodec.depthac", "max_error": -1}, {"id": "pcdcodec.png16", "level": 99},
            {"id": "pcdcodec.nope"}, {"id": "pcdcodec.h264"}, {"id": "pcdcodec.zstd", "level": None},
            {"id": "pcdcodec.depthac", "max_error": float("nan")}]:
    t(f"get_codec {cfg}", lambda: numcodecs.get_codec(dict(cfg)))
t("numcodec_class(3)", lambda: pcdcodec.zarr.numcodec_class(3))
t("DepthAC.from_config wrong id", lambda: pcdcodec.zarr.numcodecs.DepthAC.from_config({"id": "pcdcodec.rvl"}))
