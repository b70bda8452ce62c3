"""framesets=True over a rig whose second camera recorded no frame: the dataset is made with 0
items, without a word, and a shuffled DataLoader over it fails in torch with a ValueError that
says nothing of cameras or frames."""
import tempfile, pcdcodec
from pcdcodec import CameraSpec
import pcdcodec.torch as pt
from torch.utils.data import DataLoader
seq = pcdcodec.load_sample(); frames = list(seq)[:4]
path = tempfile.mkdtemp() + "/rig.pcdc"
cams = [CameraSpec("head", seq.intrinsics, seq.depth_scale, fps=30.0),
        CameraSpec("wrist", seq.intrinsics, seq.depth_scale, fps=30.0)]
with pcdcodec.open(path, "w", cameras=cams) as w:
    for f in frames:
        w.write("head", f.color, f.depth, f.timestamp_ns)  # wrist never writes
try:
    ds = pt.RecordingDataset(path, ["depth"], framesets=True)
    print("dataset made:", ds)
    next(iter(DataLoader(ds, batch_size=2, shuffle=True)))
except Exception as e:
    print(f"{type(e).__name__}: {e} | a PcdcodecError: {isinstance(e, pcdcodec.PcdcodecError)}")
