import os, shutil, tempfile, pickle, numpy as np, pcdcodec
from pcdcodec import CameraIntrinsics, CameraSpec
import pcdcodec.torch as pt
def t(label, f):
    try:
        r = f(); print("OK  ", label, r)
    except pcdcodec.PcdcodecError as e:
        print("PCD ", label, type(e).__name__, e)
    except Exception as e:
        print("FOREIGN", label, type(e).__name__, e)
seq = pcdcodec.load_sample(); frames = list(seq)[:6]
tmp = tempfile.mkdtemp()
def one(path, n=6, **kw):
    kw.setdefault("overwrite", True)
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, **kw) as w:
        for f in frames[:n]:
            w.write(f.color if kw.get("color", 1) is not None else None, f.depth, f.timestamp_ns, pose=f.pose)
    return path
a = one(f"{tmp}/a.pcdc")
# rig where 'wrist' has no frames at all
cam = seq.intrinsics
def rig(path, wrist_frames):
    cams = [CameraSpec("head", cam, seq.depth_scale, fps=30.0), CameraSpec("wrist", cam, seq.depth_scale, fps=30.0)]
    with pcdcodec.open(path, "w", cameras=cams) as w:
        for k, f in enumerate(frames):
            w.write("head", f.color, f.depth, f.timestamp_ns)
            if k < wrist_frames:
                w.write("wrist", f.color, f.depth, f.timestamp_ns)
    return path
r0 = rig(f"{tmp}/r0.pcdc", 0)
t("rig wrist 0 frames, framesets", lambda: len(pt.RecordingDataset(r0, ["depth"], framesets=True)))
t("rig wrist 0 frames, items", lambda: len(pt.RecordingDataset(r0, ["depth"])))
t("rig wrist 0 frames, cameras=[wrist], framesets", lambda: len(pt.RecordingDataset(r0, ["depth"], framesets=True, cameras=["wrist"])))
t("rig wrist 0 frames, cameras=[wrist,head], framesets", lambda: len(pt.RecordingDataset(r0, ["depth"], framesets=True, cameras=["wrist", "head"])))
t("rig + one-camera file, framesets", lambda: len(pt.RecordingDataset([r0, a], ["depth"], framesets=True)))
ds = pt.RecordingDataset(a, ["depth", "index"])
t("numpy int index", lambda: ds[np.int64(-1)]["index"])
t("numpy uint index", lambda: ds[np.uint8(3)]["index"])
t("negative index", lambda: ds[-6]["index"])
t("index -7", lambda: ds[-7])
t("index torch tensor", lambda: ds[__import__("torch").tensor(2)]["index"])
t("index huge uint64", lambda: ds[np.uint64(2**63)])
t("fields misspelled", lambda: pt.RecordingDataset(a, ["dpeth"]))
t("fields None", lambda: pt.RecordingDataset(a, None))
t("fields dict", lambda: pt.RecordingDataset(a, {"depth": 1}))
t("fields [3]", lambda: pt.RecordingDataset(a, [3]))
t("fields [['depth']]", lambda: pt.RecordingDataset(a, [["depth"]]))
t("cameras misspelled", lambda: pt.RecordingDataset(a, cameras=["Camera"]))
t("cameras generator", lambda: len(pt.RecordingDataset(r0, cameras=(c for c in ["head"]))))
t("cameras dup", lambda: len(pt.RecordingDataset(r0, ["depth"], cameras=["head", "head"])))
t("cameras dup framesets", lambda: pt.RecordingDataset(r0, ["index"], cameras=["head", "head"], framesets=True)[0])
t("cameras 3", lambda: pt.RecordingDataset(a, cameras=3))
t("tolerance -1", lambda: pt.RecordingDataset(r0, framesets=True, tolerance=-1))
t("max_open 0", lambda: pt.RecordingDataset(a, max_open=0))
t("empty list", lambda: pt.RecordingDataset([]))
t("list with None", lambda: pt.RecordingDataset([None]))
t("bytes path", lambda: pt.RecordingDataset(a.encode()))
os.makedirs(f"{tmp}/empty"); t("empty folder", lambda: pt.RecordingDataset(f"{tmp}/empty"))
t("glob nothing", lambda: pt.RecordingDataset(f"{tmp}/*.nope"))
t("glob dir only", lambda: pt.RecordingDataset(f"{tmp}/emp*"))
t("glob matches non-recordings", lambda: pt.RecordingDataset(f"{tmp}/*"))
open(f"{tmp}/bad.txt", "w").write("hello")
t("a text file", lambda: pt.RecordingDataset(f"{tmp}/bad.txt"))
os.makedirs(f"{tmp}/withbad"); shutil.copy(a, f"{tmp}/withbad/a.pcdc"); open(f"{tmp}/withbad/z.pcdc", "wb").write(b"\x89MCAP0\r\n" + os.urandom(500))
t("folder with a garbage .pcdc", lambda: pt.RecordingDataset(f"{tmp}/withbad"))
open(f"{tmp}/empty.pcdc", "wb").close()
t("zero-byte .pcdc", lambda: pt.RecordingDataset(f"{tmp}/empty.pcdc"))
t("a folder named x.pcdc inside", lambda: (os.makedirs(f"{tmp}/f2/x.pcdc/"), shutil.copy(a, f"{tmp}/f2/b.pcdc"), pt.RecordingDataset(f"{tmp}/f2").sources)[-1])
# recording with zero frames
with pcdcodec.open(f"{tmp}/zero.pcdc", "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
    pass
t("zero frames file", lambda: len(pt.RecordingDataset(f"{tmp}/zero.pcdc")))
t("zero frames + a", lambda: pt.RecordingDataset([f"{tmp}/zero.pcdc", a], ["index", "source"])[0])
t("zero frames iter", lambda: list(pt.IterableRecordingDataset(f"{tmp}/zero.pcdc")))
# deleted after dataset made
c = shutil.copy(a, f"{tmp}/c.pcdc")
dc = pt.RecordingDataset(c, ["depth"])
os.remove(c)
t("deleted recording", lambda: dc[0])
# replaced with a shorter one
c = one(f"{tmp}/d.pcdc")
dd = pt.RecordingDataset(c, ["depth"]); dd2 = pt.RecordingDataset(c, ["color"])
one(f"{tmp}/d.pcdc", n=2)
t("replaced shorter, depth", lambda: dd[4])
t("replaced shorter, color", lambda: dd2[4])
# replaced with garbage
c = one(f"{tmp}/e.pcdc"); de = pt.RecordingDataset(c, ["depth"])
open(c, "wb").write(os.urandom(3000))
t("replaced with garbage", lambda: de[1])
# pickles
t("pickle size", lambda: len(pickle.dumps(pt.RecordingDataset(a))))
t("pickle lambda transform", lambda: len(pickle.dumps(pt.RecordingDataset(a, transform=lambda x: x))))
# float depth with nan/inf
fl = f"{tmp}/float.pcdc"
with pcdcodec.open(fl, "w", intrinsics=seq.intrinsics, depth_scale=1.0) as w:
    for f in frames[:2]:
        dep = (f.depth / np.float32(1000)).astype(np.float32); dep[dep == 0] = np.nan; dep[0, 0] = np.inf; dep[0, 1] = -np.inf; dep[0,2] = -1.0
        w.write(f.color, dep, f.timestamp_ns)
fd = pt.RecordingDataset(fl, ["depth", "depth_metres", "points", "organized"])
def chk():
    it = fd[0]
    return (it["depth"].dtype, np.isnan(it["depth"]).sum(), it["depth_metres"][0, :3], np.isfinite(it["points"]).all(), len(it["points"]), it["organized"][0, :3])
t("float depth", chk)
t("float depth tensors", lambda: pt.RecordingDataset(fl, ["depth"], tensors=True)[0]["depth"].dtype)
t("uint16 tensors", lambda: pt.RecordingDataset(a, ["depth", "pose", "intrinsics", "rig_pose"], tensors=True)[0]["pose"].dtype)
t("repr", lambda: repr(pt.IterableRecordingDataset(a)))
