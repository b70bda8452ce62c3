"""Compare every codec on your own RGB-D data: pytest examples/benchmark_my_data.py
--pcdcodec-data path/to/folder --benchmark-only (without --pcdcodec-data: the bundled sample)."""

from pcdcodec.testing import bench_color, bench_depth


def test_depth(benchmark, rgbd_sequence, depth_codec):
    bench_depth(benchmark, depth_codec, rgbd_sequence, op="encode")


def test_color(benchmark, rgbd_sequence, color_codec):
    bench_color(benchmark, color_codec, rgbd_sequence, op="encode")
