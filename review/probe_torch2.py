import tempfile, numpy as np, pcdcodec, pickle
import pcdcodec.torch as pt
from torch.utils.data import DataLoader
seq = pcdcodec.load_sample(); frames = list(seq)[:5]
if __name__ == "__main__":
    tmp = tempfile.mkdtemp()
    paths = []
    for k in range(3):
        p = f"{tmp}/r{k}.pcdc"; paths.append(p)
        with pcdcodec.open(p, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
            for j, f in enumerate(frames if k % 2 == 0 else frames[::-1]):
                w.write(f.color, f.depth, j * 33_000_000, pose=f.pose)
    ref = pt.RecordingDataset(paths, ["color", "depth", "source", "index"])
    small = pt.RecordingDataset(paths, ["color", "depth", "source", "index"], max_open=1)
    rng = np.random.default_rng(0)
    ok = True
    for i in rng.integers(0, len(ref), 40):
        x, y = ref[int(i)], small[int(i)]
        ok &= np.array_equal(x["color"], y["color"]) and np.array_equal(x["depth"], y["depth"])
    print("max_open=1 random equal:", ok, "open now:", len(small._readers._open))
    ds = pt.RecordingDataset(paths, ["depth", "depth_metres", "timestamp", "pose", "color"], tensors=True)
    for ctx in ("fork", "spawn"):
        b = next(iter(DataLoader(ds, batch_size=4, num_workers=2, multiprocessing_context=ctx)))
        print(ctx, {k: (tuple(v.shape), v.dtype) for k, v in b.items()})
    # persistent workers, several epochs, iterable
    it = pt.IterableRecordingDataset(paths, ["source", "index"])
    dl = DataLoader(it, batch_size=None, num_workers=2, persistent_workers=True, multiprocessing_context="spawn")
    for epoch in range(2):
        got = sorted((s, int(i)) for s, i in ((x["source"], x["index"]) for x in dl))
        print("epoch", epoch, len(got), len(set(got)))
