"""Measure pcdcodec on each real source: sizes, exact depth, and colored-cloud error.

For every source present under ``../shared/data`` (RealSense .bag, Azure Kinect .mkv, and the
TUM, 7-Scenes and D435 folders) it records the frames twice (default codecs; lossless FFV1
color), checks that every decoded depth image equals the source's, and compares the colored
cloud rebuilt from the recording with the source's own registration:

* registered folders: the cloud of the original frames (same pixels, so the point error is the
  depth error, and the color error is the video coding's);
* RealSense: librealsense's ``rs2::align`` depth (from ``--rs-reference``, made by
  ``scripts/realsense_align_reference.py``) back-projected with the color camera, each point
  colored by its color pixel; distances are from each reference point to the nearest rebuilt
  point, in the color camera's frame;
* Azure Kinect: the SDK is not available here, so the reference is a registration computed
  with OpenCV's ``projectPoints`` (rational model), back-projected the same way.

Prints a Markdown table. Run: ``python scripts/measure_ingest.py [--rs-reference REF.npz]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec import CameraIntrinsics, Projector
from pcdcodec.datasets import open_folder

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def sources() -> list[tuple[str, Any, int]]:
    """(name, opened source, input bytes) for each real source present."""
    out: list[tuple[str, Any, int]] = []
    bag = DATA / "bags" / "realsense" / "single_depth_color_640x480.bag"
    if bag.exists():
        # Its one color frame is 101 ms from the nearer depth frame: pair that one.
        rs = pcdcodec.open_source(bag, max_difference=150_000_000)
        out.append(("RealSense D435 `.bag`", rs, bag.stat().st_size))
    mkv = DATA / "bags" / "pyk4a_recording.mkv"
    if mkv.exists():
        out.append(("Azure Kinect `.mkv`", pcdcodec.open_source(mkv), mkv.stat().st_size))
    folders = [
        (
            "TUM fr1_rpy folder",
            "tum_fr1_rpy",
            CameraIntrinsics(640, 480, 525, 525, 319.5, 239.5),
            5000.0,
        ),
        (
            "7-Scenes redkitchen folder",
            "7scenes_redkitchen",
            CameraIntrinsics(640, 480, 585, 585, 320, 240),
            1000.0,
        ),
        (
            "D435 office folder",
            "realsense_d435_office",
            CameraIntrinsics(640, 480, 615, 615, 320, 240),
            1000.0,
        ),
    ]
    for name, sub, intr, scale in folders:
        root = DATA / sub
        if root.is_dir():
            # The D435 folder's "timestamps" are not times: pair its images by name.
            layout = "folders" if sub == "realsense_d435_office" else "auto"
            src = open_folder(root, intrinsics=intr, depth_scale=scale, layout=layout)
            size = sum(c.stat().st_size + d.stat().st_size for _, c, d in src.pairs)
            out.append((name, src, size))
    return out


def record(src: Any, frames: list[Any], path: Path, color: str) -> int:
    with pcdcodec.open(
        path,
        "w",
        intrinsics=src.intrinsics,
        depth_scale=src.depth_scale,
        color=color,
        color_intrinsics=src.color_intrinsics,
        depth_to_color=src.depth_to_color,
        metadata=src.metadata or None,
        overwrite=True,
    ) as rec:
        rec.write_frames(frames)
    return path.stat().st_size


def nn_error(
    ref_pts: np.ndarray, ref_rgb: np.ndarray, pts: np.ndarray, rgb: np.ndarray
) -> tuple[float, float, float, float]:
    """Median, mean and 95th percentile distance (mm) from each reference point to the nearest
    rebuilt point, and the mean color difference (0-255) of those pairs."""
    import open3d as o3d

    nns = o3d.core.nns.NearestNeighborSearch(o3d.core.Tensor(np.ascontiguousarray(pts, np.float64)))
    nns.knn_index()
    j, d2 = nns.knn_search(o3d.core.Tensor(np.ascontiguousarray(ref_pts, np.float64)), 1)
    idx = j.numpy()[:, 0].astype(np.int64)
    dist = np.sqrt(d2.numpy()[:, 0])
    dc = np.abs(ref_rgb.astype(np.int32) - rgb[idx].astype(np.int32)).mean()
    mm = dist * 1000
    return float(np.median(mm)), float(mm.mean()), float(np.percentile(mm, 95)), float(dc)


def registered_cloud(depth_c: np.ndarray, color: np.ndarray, cam: CameraIntrinsics, scale: float):
    """A registered depth image (color camera) back-projected, colored by its own pixels."""
    proj = Projector(cam, scale)
    return proj.to_points(depth_c, color)


def opencv_registration(depth: np.ndarray, src: Any) -> np.ndarray:
    """Depth registered to the color camera with OpenCV's projection, nearest point per pixel."""
    import cv2

    cam, color = src.intrinsics, src.color_intrinsics
    pts, _ = Projector(cam, src.depth_scale).to_points(depth)
    moved = pts.astype(np.float64) @ src.depth_to_color[:3, :3].T + src.depth_to_color[:3, 3]
    uv, _ = cv2.projectPoints(
        moved.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), color.K, np.asarray(color.distortion)
    )
    uv = np.floor(uv.reshape(-1, 2) + 0.5).astype(np.int64)
    ok = (uv[:, 0] >= 0) & (uv[:, 0] < color.width) & (uv[:, 1] >= 0) & (uv[:, 1] < color.height)
    ok &= moved[:, 2] > 0
    out = np.full(color.height * color.width, np.inf)
    np.minimum.at(out, uv[ok, 1] * color.width + uv[ok, 0], moved[ok, 2] * src.depth_scale)
    out[~np.isfinite(out)] = 0
    return out.reshape(color.height, color.width).astype(np.float32)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rs-reference", type=Path, help="npz from realsense_align_reference.py")
    args = parser.parse_args()
    rs_ref = np.load(args.rs_reference) if args.rs_reference else None
    tmp = Path(tempfile.mkdtemp())
    rows = []
    for name, src, input_size in sources():
        t0 = time.perf_counter()
        frames = list(src)
        n = len(frames)
        size_default = record(src, frames, tmp / "d.pcdc", "h264")
        size_lossless = record(src, frames, tmp / "l.pcdc", "ffv1")
        exact = True
        errors: list[tuple[float, float, float, float]] = []
        lossless_color = []
        for path in (tmp / "d.pcdc", tmp / "l.pcdc"):
            with pcdcodec.open(path) as rec:
                for i, (got, want) in enumerate(zip(rec, frames, strict=True)):
                    exact &= bool(np.array_equal(got.depth, want.depth))
                    if path.name == "l.pcdc":
                        lossless_color.append(bool(np.array_equal(got.color, want.color)))
                        continue
                    if src.color_intrinsics is None:
                        if i % max(1, n // 10):  # ten frames are enough for the color error
                            continue
                        ref_pts, ref_rgb = Projector(src.intrinsics, src.depth_scale).to_points(
                            want.depth, want.color
                        )
                        pts, rgb = got.to_points()
                        point = float(np.abs(pts - ref_pts).max()) * 1000
                        dc = float(np.abs(ref_rgb.astype(int) - rgb.astype(int)).mean())
                        errors.append((point, point, point, dc))
                        continue
                    ref_depth = None
                    if "RealSense" in name and rs_ref is not None:
                        crc = zlib.crc32(want.depth.tobytes())
                        for k in range(int(rs_ref["count"])):
                            if zlib.crc32(rs_ref[f"depth{k}"].tobytes()) == crc:
                                ref_depth = rs_ref[f"aligned{k}"]
                    elif "Azure" in name:
                        ref_depth = opencv_registration(want.depth, src)
                    if ref_depth is None:
                        continue
                    ref_pts, ref_rgb = registered_cloud(
                        ref_depth, want.color, src.color_intrinsics, src.depth_scale
                    )
                    pts, rgb = got.to_points()
                    d2c = src.depth_to_color
                    moved = pts.astype(np.float64) @ d2c[:3, :3].T + d2c[:3, 3]
                    errors.append(nn_error(ref_pts, ref_rgb, moved, rgb))
        err = np.array(errors) if errors else None
        rows.append(
            (
                name,
                n,
                input_size,
                size_default,
                size_lossless,
                exact,
                all(lossless_color),
                err,
                time.perf_counter() - t0,
            )
        )
        src.close()
    print(
        f"| source | frames | input | .pcdc default (h264 + {pcdcodec.DEFAULT_DEPTH_CODEC}) | "
        f".pcdc lossless color (ffv1 + {pcdcodec.DEFAULT_DEPTH_CODEC}) | depth bit-exact | "
        "point error vs source registration, mm (median / mean / p95) | color error of those "
        "points (0-255, default codecs) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, n, size_in, size_d, size_l, exact, ll, err, _ in rows:

        def kib(b: int) -> str:
            return f"{b / 1024:,.0f} KiB"

        if err is None:
            e, c = "n/a", "n/a"
        else:
            e = f"{np.median(err[:, 0]):.2f} / {err[:, 1].mean():.2f} / {np.median(err[:, 2]):.2f}"
            c = f"{err[:, 3].mean():.2f}"
        print(
            f"| {name} | {n} | {kib(size_in)} | {kib(size_d)} ({size_in / size_d:.1f}x) | "
            f"{kib(size_l)} ({size_in / size_l:.1f}x){'' if ll else ' (color NOT exact)'} | "
            f"{'yes' if exact else 'NO'} | {e} | {c} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
