"""RecordingDataset's cameras= and fields= arguments: a generator of names gives an empty
dataset silently, a camera named twice doubles every frame (and a frame set silently drops the
repeat), and a non-iterable cameras or a list inside fields raise a bare TypeError."""
import tempfile, numpy as np, pcdcodec
from pcdcodec import CameraSpec
import pcdcodec.torch as pt
seq = pcdcodec.load_sample(); frames = list(seq)[:4]
path = tempfile.mkdtemp() + "/rig.pcdc"
cams = [CameraSpec("head", seq.intrinsics, seq.depth_scale, fps=30.0),
        CameraSpec("wrist", seq.intrinsics, seq.depth_scale, fps=30.0)]
with pcdcodec.open(path, "w", cameras=cams) as w:
    for f in frames:
        w.write("head", f.color, f.depth, f.timestamp_ns)
        w.write("wrist", f.color, f.depth, f.timestamp_ns)
def t(label, f):
    try:
        print(label, "->", f())
    except Exception as e:
        print(label, "->", type(e).__name__, e, "| a PcdcodecError:", isinstance(e, pcdcodec.PcdcodecError))
t("cameras=(c for c in ['head']): len", lambda: len(pt.RecordingDataset(path, ["index"], cameras=(c for c in ["head"]))))
t("cameras=['head', 'head']: len (4 head frames)", lambda: len(pt.RecordingDataset(path, ["index"], cameras=["head", "head"])))
t("cameras=['head', 'head'], framesets: item 0", lambda: pt.RecordingDataset(path, ["index"], cameras=["head", "head"], framesets=True)[0])
t("cameras=3", lambda: pt.RecordingDataset(path, cameras=3))
t("fields=[['depth']]", lambda: pt.RecordingDataset(path, [["depth"]]))
