"""pcdcodec view --points with the default stride (2) on a recording whose color camera differs
from its depth camera (a smaller color image, as Azure Kinect/RealSense files may hold): the
points take their colors from the color image at depth pixel positions."""
import tempfile, numpy as np, pcdcodec
from pcdcodec import CameraIntrinsics
from pcdcodec.viewer import view
seq = pcdcodec.load_sample(); frames = list(seq)[:2]
tmp = tempfile.mkdtemp()
cam = seq.intrinsics
color_cam = CameraIntrinsics(320, 240, cam.fx / 2, cam.fy / 2, cam.cx / 2, cam.cy / 2)
path = f"{tmp}/two.pcdc"
with pcdcodec.open(path, "w", intrinsics=cam, depth_scale=seq.depth_scale,
                   color_intrinsics=color_cam, depth_to_color=np.eye(4)) as w:
    for f in frames:
        w.write(np.ascontiguousarray(f.color[::2, ::2]), f.depth, f.timestamp_ns)
for stride in (1, 2):
    try:
        view(path, save=f"{tmp}/out{stride}.rrd", points=True, stride=stride)
        print(f"stride {stride}: written")
    except Exception as e:
        print(f"stride {stride}: {type(e).__name__}: {e} | a PcdcodecError: {isinstance(e, pcdcodec.PcdcodecError)}")
