"""float32 depth recorded with depth_scale 1000 (millimetres): pcdcodec's points divide it by
depth_scale, but view logs the depth image with meter=1.0, so Rerun places it 1000 x farther."""
import tempfile, numpy as np, pcdcodec
from pcdcodec.viewer import view
from rerun.chunk import RrdReader
seq = pcdcodec.load_sample(); f = seq[0]
tmp = tempfile.mkdtemp(); path = f"{tmp}/mm.pcdc"
mm = (f.depth.astype(np.float32) / np.float32(seq.depth_scale) * 1000).astype(np.float32)
with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=1000.0, depth="depthac") as w:
    w.write(f.color, mm, f.timestamp_ns)
with pcdcodec.open(path) as rec:
    frame = rec[0]
    pts, _ = frame.to_points()
    print("recording depth_scale:", rec.depth_scale, "| median z of pcdcodec's points (m):", float(np.median(pts[:, 2])))
    print("median depth value (float32):", float(np.nanmedian(frame.depth[frame.depth > 0])))
view(path, save=f"{tmp}/o.rrd")
for chunk in RrdReader(f"{tmp}/o.rrd").stream():
    if chunk.entity_path == "/world/camera/image/depth":
        b = chunk.to_record_batch()
        for name in b.schema.names:
            if name.endswith("meter"):
                print("logged", name, b.column(name).to_pylist())
