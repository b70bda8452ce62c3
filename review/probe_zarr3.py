import tempfile, os, glob, numpy as np, zarr, pcdcodec
from pcdcodec.zarr import serializer, DepthSerializer
def t(label, f):
    try:
        r = f(); print("OK  ", label, r if not hasattr(r, "shape") else r.shape)
    except pcdcodec.PcdcodecError as e:
        print("PCD ", label, type(e).__name__, e)
    except Exception as e:
        print("FOREIGN", label, type(e).__name__, e)
d = np.stack(pcdcodec.load_sample().depths[:3])
tmp = tempfile.mkdtemp()
t("hash", lambda: hash(serializer()))
t("eq", lambda: serializer() == serializer("depthac"))
for cfg in [{"name": "pcdcodec.depthac", "configuration": {"bogus": 1}}, {"name": "pcdcodec.depthac", "configuration": {"id": "rvl"}},
            {"name": "pcdcodec.depthac", "configuration": []}, {"name": "pcdcodec.nope"}, {"name": "pcdcodec.h264"}, {"name": 3}, {}]:
    t(f"from_dict {cfg}", lambda: DepthSerializer.from_dict(cfg).to_dict())
t("serializer('depthac', bogus=1)", lambda: serializer("depthac", bogus=1))
t("serializer(3)", lambda: serializer(3))
t("serializer('h264')", lambda: serializer("h264"))
a = zarr.create_array(f"{tmp}/a.zarr", shape=d.shape, chunks=(1, *d.shape[1:]), dtype=d.dtype, serializer=serializer("depthac"), compressors=None)
a[:] = d
files = sorted(glob.glob(f"{tmp}/a.zarr/c/*/*/*"))
print(files)
raw = open(files[1], "rb").read()
rng = np.random.default_rng(1)
def corrupt(data):
    open(files[1], "wb").write(data)
    return zarr.open_array(f"{tmp}/a.zarr", mode="r")[1]
t("truncated chunk", lambda: corrupt(raw[: len(raw) // 2]))
t("empty chunk", lambda: corrupt(b""))
t("random chunk", lambda: corrupt(rng.bytes(5000)))
for k in range(20):
    b = bytearray(raw); b[int(rng.integers(len(b)))] ^= 1 << int(rng.integers(8))
    t(f"bitflip {k}", lambda: corrupt(bytes(b)))
# chunk encoded with another codec / other shape
from pcdcodec.zarr import numcodec
t("chunk other shape", lambda: corrupt(numcodec("depthac").encode(d[0][:100, :100])))
t("chunk float32", lambda: corrupt(numcodec("depthac").encode(d[0].astype(np.float32))))
t("chunk other codec", lambda: corrupt(numcodec("zstd").encode(d[0])))
open(files[1], "wb").write(raw)
# float32
f = d.astype(np.float32) / 1000; f[f == 0] = np.nan; f[0, 0, 0] = np.inf; f[0,0,1] = -0.0
b = zarr.create_array(f"{tmp}/f.zarr", shape=f.shape, chunks=(1, *f.shape[1:]), dtype=f.dtype, serializer=serializer("depthac"), compressors=None)
b[:] = f
back = zarr.open_array(f"{tmp}/f.zarr")[:]
print("float32 bit exact:", back.view(np.uint32).tobytes() == f.view(np.uint32).tobytes())
# tiles, edge padding, fill value nan
c = zarr.create_array(f"{tmp}/t.zarr", shape=(3, 479, 641), chunks=(1, 100, 100), dtype="float32", serializer=serializer("depthac"), compressors=None, fill_value=np.nan)
g = np.pad(f[:, :479, :], ((0,0),(0,0),(0,1)), constant_values=1.5)
c[:] = g
back = zarr.open_array(f"{tmp}/t.zarr")[:]
print("tiles float32 bit exact:", back.view(np.uint32).tobytes() == g.view(np.uint32).tobytes())
t("chunks 2 frames", lambda: zarr.create_array(f"{tmp}/x.zarr", shape=d.shape, chunks=(2, *d.shape[1:]), dtype=d.dtype, serializer=serializer("depthac"), compressors=None))
t("int32", lambda: zarr.create_array(f"{tmp}/y.zarr", shape=d.shape, chunks=(1, *d.shape[1:]), dtype="int32", serializer=serializer("depthac"), compressors=None))
t("1d", lambda: zarr.create_array(f"{tmp}/z.zarr", shape=(10,), chunks=(10,), dtype="uint16", serializer=serializer("depthac"), compressors=None))
t("png16 float", lambda: zarr.create_array(f"{tmp}/w.zarr", shape=d.shape, chunks=(1, *d.shape[1:]), dtype="float32", serializer=serializer("png16"), compressors=None))
t("float64", lambda: zarr.create_array(f"{tmp}/v.zarr", shape=d.shape, chunks=(1, *d.shape[1:]), dtype="float64", serializer=serializer("depthac"), compressors=None))
# shape with a zero-length axis
t("empty array", lambda: zarr.create_array(f"{tmp}/e.zarr", shape=(0, 480, 640), chunks=(1, 480, 640), dtype="uint16", serializer=serializer("depthac"), compressors=None)[:])
# sharding
s = zarr.create_array(f"{tmp}/s.zarr", shape=d.shape, chunks=(1, 240, 320), shards=(3, 480, 640), dtype=d.dtype, serializer=serializer("depthac"), compressors=None)
s[:] = d
print("sharded equal", np.array_equal(zarr.open_array(f"{tmp}/s.zarr")[:], d))
# partial write of a frame region
p = zarr.create_array(f"{tmp}/p.zarr", shape=d.shape, chunks=(1, *d.shape[1:]), dtype=d.dtype, serializer=serializer("depthac"), compressors=None)
p[:] = d; p[1, 10:20, 10:20] = 7; want = d.copy(); want[1, 10:20, 10:20] = 7
print("partial update equal", np.array_equal(p[:], want))
