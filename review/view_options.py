"""pcdcodec.view's options: max_frames and jpeg_quality are not checked (a bare TypeError, or
color silently left out of the .rrd with only a Rerun warning; 0 logs raw images), a --save
into a missing folder raises Rerun's RuntimeError, and a recording that fails part way leaves
its hidden .partial file beside the target."""
import glob, os, tempfile, warnings, numpy as np, pcdcodec
from pcdcodec.viewer import view
from rerun.chunk import RrdReader
seq = pcdcodec.load_sample(); frames = list(seq)[:4]
tmp = tempfile.mkdtemp()
a = f"{tmp}/a.pcdc"
with pcdcodec.open(a, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
    for f in frames:
        w.write(f.color, f.depth, f.timestamp_ns)
def t(label, **kw):
    out = f"{tmp}/o.rrd"
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            view(a, save=out, **kw)
        rgb = [c for c in RrdReader(out).stream() if c.entity_path == "/world/camera/image/rgb"]
        cols = sorted({n for c in rgb for n in c.to_record_batch().schema.names if n.startswith(("Image:", "EncodedImage:"))})
        print(f"{label}: no error; rgb columns {cols}; warnings {[str(w.message) for w in caught]}")
    except Exception as e:
        print(f"{label}: {type(e).__name__}: {e} | a PcdcodecError: {isinstance(e, pcdcodec.PcdcodecError)}")
t("max_frames=2.5", max_frames=2.5)
t("max_frames='3'", max_frames="3")
t("jpeg_quality=90 (default)", video=False)
t("jpeg_quality=0", jpeg_quality=0, video=False)
t("jpeg_quality=101", jpeg_quality=101, video=False)
t("jpeg_quality='x'", jpeg_quality="x", video=False)
t("jpeg_quality=-5", jpeg_quality=-5, video=False)
try:
    view(a, save=f"{tmp}/missing/o.rrd")
except Exception as e:
    print(f"save into a missing folder: {type(e).__name__}: {e} | a PcdcodecError: {isinstance(e, pcdcodec.PcdcodecError)}")
data = open(a, "rb").read()
open(f"{tmp}/cut.pcdc", "wb").write(data[: len(data) * 2 // 3])
try:
    view(f"{tmp}/cut.pcdc", save=f"{tmp}/cut.rrd")
except pcdcodec.DecodeError as e:
    print("truncated recording: DecodeError; left beside the target:", [os.path.basename(p) for p in glob.glob(f"{tmp}/.cut.rrd*")])
