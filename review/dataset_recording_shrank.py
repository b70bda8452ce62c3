"""A recording rewritten shorter after the dataset was made: items past its end raise a bare
IndexError, which ends plain iteration silently (frames lost, no error)."""
import tempfile, numpy as np, pcdcodec
import pcdcodec.torch as pt
seq = pcdcodec.load_sample(); frames = list(seq)[:6]
tmp = tempfile.mkdtemp()
def write(path, n):
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, overwrite=True) as w:
        for f in frames[:n]:
            w.write(f.color, f.depth, f.timestamp_ns)
path = f"{tmp}/a.pcdc"
write(path, 6)
ds = pt.RecordingDataset(path, ["depth", "index"])
print("len(ds) =", len(ds))
write(path, 2)  # the recording is rewritten with 2 frames
items = list(ds)  # sequence protocol: stops at the first IndexError
print("list(ds) gave", len(items), "items, no error")
try:
    ds[4]
except Exception as e:
    print("ds[4]:", type(e).__name__, e, "| a PcdcodecError:", isinstance(e, pcdcodec.PcdcodecError))
