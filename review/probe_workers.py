import sys, tempfile, numpy as np, pcdcodec
import pcdcodec.torch as pt
from torch.utils.data import DataLoader
seq = pcdcodec.load_sample(); frames = list(seq)[:5]
tmp = tempfile.mkdtemp()
def one(path, n):
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
        for f in frames[:n]:
            w.write(f.color, f.depth, f.timestamp_ns, pose=f.pose)
    return path
if __name__ == "__main__":
    a = one(f"{tmp}/a.pcdc", 5); b = one(f"{tmp}/b.pcdc", 3)
    for ctx in ("fork", "spawn"):
        for workers in (1, 2, 3, 7, 8, 9):
            ds = pt.IterableRecordingDataset([a, b], ["source", "index"])
            got = [(s, int(i)) for batch in DataLoader(ds, batch_size=2, num_workers=workers, multiprocessing_context=ctx) for s, i in zip(batch["source"], batch["index"])]
            want = [(a, i) for i in range(5)] + [(b, i) for i in range(3)]
            print(ctx, workers, "each once:", sorted(got) == sorted(want), len(got))
    # fork after the parent decoded color with FFmpeg's own threads
    ds = pt.RecordingDataset([a, b], ["color", "depth"], threads=None)
    ds[0]; ds[6]
    n = sum(len(x["color"]) for x in DataLoader(ds, batch_size=2, num_workers=2, multiprocessing_context="fork", timeout=60))
    print("fork after threads=None read", n)
    n = sum(len(x["color"]) for x in DataLoader(ds, batch_size=2, num_workers=2, multiprocessing_context="fork", persistent_workers=True, timeout=60))
    print("persistent", n)
