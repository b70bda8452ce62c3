import os, tempfile, glob, numpy as np, pcdcodec
from pcdcodec import CameraSpec
from pcdcodec.viewer import view
seq = pcdcodec.load_sample(); frames = list(seq)[:4]
tmp = tempfile.mkdtemp()
def t(label, f):
    try:
        r = f(); print("OK  ", label, r)
    except pcdcodec.PcdcodecError as e:
        print("PCD ", label, type(e).__name__, e)
    except Exception as e:
        print("FOREIGN", label, type(e).__name__, e)
a = f"{tmp}/a.pcdc"
with pcdcodec.open(a, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
    for f in frames: w.write(f.color, f.depth, f.timestamp_ns, pose=f.pose)
out = f"{tmp}/o.rrd"
t("max_frames 2.5", lambda: view(a, save=out, max_frames=2.5))
t("max_frames '3'", lambda: view(a, save=out, max_frames="3"))
t("max_frames True", lambda: view(a, save=out, max_frames=True))
t("jpeg_quality 0", lambda: view(a, save=out, jpeg_quality=0, video=False))
t("jpeg_quality 101", lambda: view(a, save=out, jpeg_quality=101, video=False))
t("jpeg_quality 'x'", lambda: view(a, save=out, jpeg_quality="x", video=False))
t("jpeg_quality -5", lambda: view(a, save=out, jpeg_quality=-5, video=False))
t("save in missing dir", lambda: view(a, save=f"{tmp}/nodir/o.rrd"))
t("threads -1", lambda: view(a, save=out, threads=-1))
t("every 3", lambda: view(a, save=out, every=3))
t("every 3 points", lambda: view(a, save=out, every=3, points=True, threads=2))
t("depth_format rvl threads 2", lambda: view(a, save=out, depth_format="rvl", threads=2))
z = f"{tmp}/z.pcdc"
with pcdcodec.open(z, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w: pass
t("zero frames", lambda: view(z, save=out))
t("zero frames points", lambda: view(z, save=out, points=True))
r = f"{tmp}/r.pcdc"
cams = [CameraSpec("head", seq.intrinsics, seq.depth_scale, fps=30.0), CameraSpec("wrist", seq.intrinsics, seq.depth_scale, fps=30.0)]
with pcdcodec.open(r, "w", cameras=cams) as w:
    for f in frames: w.write("head", f.color, f.depth, f.timestamp_ns)
t("rig wrist without frames", lambda: view(r, save=out))
t("rig wrist without frames points", lambda: view(r, save=out, points=True))
fl = f"{tmp}/f.pcdc"
with pcdcodec.open(fl, "w", intrinsics=seq.intrinsics, depth_scale=1.0) as w:
    for f in frames:
        dep = (f.depth / np.float32(1000)).astype(np.float32); dep[dep == 0] = np.nan; dep[0, :5] = [np.inf, -np.inf, -1, 1e30, 0]
        w.write(f.color, dep, f.timestamp_ns)
t("float depth points", lambda: view(fl, save=out, points=True))
# truncated recording
data = open(a, "rb").read()
tr = f"{tmp}/t.pcdc"; open(tr, "wb").write(data[: len(data) * 2 // 3])
t("truncated recording", lambda: view(tr, save=f"{tmp}/t.rrd"))
print("left in tmp:", sorted(os.path.basename(p) for p in glob.glob(f"{tmp}/.*") + glob.glob(f"{tmp}/*")))
# bit flips in the middle
rng = np.random.default_rng(0)
for k in range(8):
    b = bytearray(data); pos = int(rng.integers(len(b) // 4, len(b) * 3 // 4)); b[pos] ^= 0x10
    bf = f"{tmp}/bf{k}.pcdc"; open(bf, "wb").write(bytes(b))
    t(f"bitflip {pos}", lambda: view(bf, save=f"{tmp}/bf.rrd"))
print("left in tmp:", sorted(os.path.basename(p) for p in glob.glob(f"{tmp}/.*")))
