"""The examples run as a user runs them and do what they say."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(script: str, *args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args],
        capture_output=True,
        text=True,
        check=False,
        cwd=cwd,
        timeout=600,
    )


def test_roundtrip_sample(tmp_path: Path) -> None:
    out = run("roundtrip_sample.py", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    for name in ("jpegxl", "lz4", "png16", "rvl", "zstd"):
        assert f"{name} " in out.stdout
    assert "NO" not in out.stdout.split("bit-exact", 1)[1]


def test_record_and_replay(tmp_path: Path) -> None:
    target = tmp_path / "s.pcdc"
    out = run("record_and_replay.py", str(target), cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert target.exists()
    assert "depth bit-exact in every frame" in out.stdout
    assert "index 7" in out.stdout


def test_compare_codecs(tmp_path: Path) -> None:
    out = run("compare_codecs.py", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "Table IV" in out.stdout
    assert (tmp_path / "codec-report" / "stream_sizes.png").exists()


def _python_blocks(doc: Path) -> list[str]:
    text = doc.read_text()
    return [block.split("```", 1)[0] for block in text.split("```python\n")[1:]]


def test_readme_python_runs_as_written(tmp_path: Path) -> None:
    """Every Python block of the README, in order, as one script (later blocks use earlier
    blocks' names). The files the README supposes the reader has are made first: ``run.bag``
    from the bundled sample, and ``recording.bag`` from the RealSense bag in the shared data
    (its one block is left out, and said to be, when that data is absent)."""
    import pcdcodec
    from pcdcodec.datasets import sample_dir

    from .conftest import SHARED_DATA

    readme = EXAMPLES.parent / "README.md"
    blocks = _python_blocks(readme)
    assert len(blocks) >= 5
    pcdcodec.encode(sample_dir(), tmp_path / "made.pcdc", max_frames=3)
    pcdcodec.export_bag(tmp_path / "made.pcdc", tmp_path / "run.bag", to="rosbag1")
    realsense = SHARED_DATA / "bags" / "realsense" / "single_depth_color_640x480.bag"
    if realsense.exists():
        (tmp_path / "recording.bag").symlink_to(realsense)
    else:
        blocks = [b for b in blocks if '"recording.bag"' not in b]
        assert len(blocks) >= 4
    script = tmp_path / "readme.py"
    marks = [f"print('README block {k} done')\n" for k in range(len(blocks))]
    script.write_text("".join(b + m for b, m in zip(blocks, marks, strict=True)))
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=600
    )
    assert out.returncode == 0, out.stderr
    assert f"README block {len(blocks) - 1} done" in out.stdout
    with pcdcodec.open(tmp_path / "o3d.pcdc") as rec:  # the Open3D block's images went in
        assert len(rec) == 15
        sample = pcdcodec.load_sample()
        assert all((rec[k].depth == sample[k].depth).all() for k in (0, 14))


def test_open3d_example(tmp_path: Path) -> None:
    out = run("open3d_rgbd.py", str(tmp_path / "r.pcdc"), cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "legacy depth equal to the written image: True" in out.stdout
    assert "Frame(index=0, timestamp_ns=1305031229528748000" in out.stdout


def test_open3d_doc_example(tmp_path: Path) -> None:
    (code,) = _python_blocks(EXAMPLES.parent / "docs" / "open3d.md")
    script = tmp_path / "doc.py"
    script.write_text(code)
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=600
    )
    assert out.returncode == 0, out.stderr
    assert "refused:" in out.stdout
    assert "depth_scale=1000" in out.stdout
    assert (tmp_path / "tensor.pcdc").exists()


def test_tsdf_fusion(tmp_path: Path) -> None:
    from pcdcodec.datasets import sample_dir

    out = run("tsdf_fusion.py", str(sample_dir()), "5", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "read back 5 frames, 5 with a pose" in out.stdout
    # Lossless depth and the stored poses rebuild the very same surface.
    assert "largest vertex distance between the meshes: 0.000 mm" in out.stdout
    mean = float(out.stdout.split("mean ", 1)[1].split(",", 1)[0])
    assert mean < 5.0  # colors differ by the video coding only


def test_rig_recording(tmp_path: Path) -> None:
    target = tmp_path / "rig.pcdc"
    out = run("rig_recording.py", str(target), cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "camera wrist: 320x240 at 15 fps, 8 frames" in out.stdout
    assert "15 frame sets, 7 without a wrist frame" in out.stdout
    assert "(missing: wrist)" in out.stdout
    assert "rig verified" in out.stdout


def test_torch_dataloader(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    out = run("torch_dataloader.py", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "shuffled, 2 workers: read 15 frames" in out.stdout
    assert "in order, 2 workers: read 15 frames" in out.stdout
    assert "(a batch of color: (" in out.stdout
