"""LiveView.log of a frame whose depth is big-endian uint16 (a valid pcdcodec.Frame): it is
logged as Rerun's raw DepthImage with the big-endian bytes, which Rerun reads little-endian."""
import tempfile, numpy as np, pcdcodec
from pcdcodec.viewer import LiveView
from rerun.chunk import RrdReader
seq = pcdcodec.load_sample(); f = seq[0]
out = tempfile.mkdtemp() + "/live.rrd"
projector = pcdcodec.Projector(seq.intrinsics, seq.depth_scale)
live = LiveView([("cam", projector)], save=out)
frame = pcdcodec.Frame(f.color, f.depth.astype(">u2"), f.timestamp_ns, projector=projector)
live.log(0, frame)
live.close()
for chunk in RrdReader(out).stream():
    if chunk.entity_path == "/world/cam/depth":
        b = chunk.to_record_batch()
        names = [n for n in b.schema.names if n.endswith(("buffer", "blob"))]
        print("logged columns:", names)
        if "DepthImage:buffer" in names:
            raw = bytes(b.column("DepthImage:buffer").to_pylist()[0][0])
            got = np.frombuffer(raw, "<u2").reshape(f.depth.shape)  # Rerun's u16: little-endian
            print("Rerun's depth equal to the frame's:", np.array_equal(got, f.depth))
        else:
            import imagecodecs
            blob = bytes(b.column("EncodedDepthImage:blob").to_pylist()[0][0])
            print("PNG depth equal to the frame's:", np.array_equal(imagecodecs.png_decode(blob), f.depth))
