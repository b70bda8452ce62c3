"""``recover`` of a real recording damaged at one point or many: every frame whose checks hold
comes back bit-exact, a frame whose color is lost keeps its depth, and the report names exactly
the frames lost and what of them.

What should come back is worked out here from the undamaged file alone: which chunks the
flipped bytes fall in, and which frames, color groups and keyframes those chunks hold."""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.damage import Layout, expected, flip
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.cli import main
from pcdcodec.recording import CameraSpec
from pcdcodec.recording import _index as fmt
from pcdcodec.recording.recover import Recovered

from .test_integrity import CAMERA, small_frames


@dataclass
class Original(Layout):
    depth: dict[int, Any] = field(default_factory=dict)
    color: dict[int, Any] = field(default_factory=dict)


@pytest.fixture(scope="module")
def tum(tmp_path_factory: pytest.TempPathFactory) -> Original:
    seq = SEQUENCES["tum_fr1_rpy"]
    if not seq.present:
        pytest.skip("TUM fr1_rpy is not in ../shared/data")
    path = tmp_path_factory.mktemp("recover") / "tum.pcdc"
    with pcdcodec.open_source(seq.root, **seq.reader_options()) as source:
        pcdcodec.encode(source, path)
    orig = Original(**vars(Layout.of(path)))
    with pcdcodec.open(path) as rec:
        assert len(rec) == 100
        orig.depth = {int(t): rec.depth(i) for i, t in enumerate(rec.timestamps.tolist())}
        orig.color = {f.timestamp_ns: f.color for f in rec}
    return orig


def check(orig: Original, flips: list[int], tmp_path: Path) -> Recovered:
    src = flip(orig, tmp_path / "damaged.pcdc", flips)
    out = tmp_path / "recovered.pcdc"
    got = pcdcodec.recover(src, out)
    dropped, no_color = expected(orig, flips)
    lost = {
        stream: {t for loss in got.lost if loss.stream == stream for t in loss.timestamps}
        for stream in ("frame", "color")
    }
    assert lost["frame"] == dropped
    assert lost["color"] == no_color
    assert got == len(orig.times) - len(dropped)
    assert got.color_missing == len(no_color)
    with pcdcodec.open(out) as rec:
        assert rec.verify().ok
        assert set(rec.timestamps.tolist()) == set(orig.times) - dropped
        assert {int(rec.timestamps[i]) for i in rec.color_missing} == no_color
        for frame in rec:
            t = frame.timestamp_ns
            np.testing.assert_array_equal(frame.depth, orig.depth[t])
            if t in no_color:
                assert frame.color is None
            else:
                np.testing.assert_array_equal(frame.color, orig.color[t])
    return got


@pytest.mark.shared_data
def test_one_flipped_byte_costs_the_color_of_one_group_only(
    tum: Original, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    got = check(tum, [2_000_000], tmp_path)
    # Before, recover kept the 43 frames before the damage and said nothing of the rest.
    assert got == 100
    assert got.dropped == 0
    assert 0 < got.color_missing < 15
    assert main(["recover", str(tmp_path / "damaged.pcdc"), "-o", str(tmp_path / "cli.pcdc")]) == 0
    out = capsys.readouterr().out
    assert f"recovered 100 frames into {tmp_path / 'cli.pcdc'}, {got.color_missing} of them" in out
    for loss in got.lost:
        assert loss.describe() in out


@pytest.mark.shared_data
@pytest.mark.parametrize("seed", [1, 2])
def test_many_flipped_bytes_lose_only_the_frames_they_reach(
    tum: Original, tmp_path: Path, seed: int
) -> None:
    rng = random.Random(seed)
    # Over the frames' chunks (the settings and the seal are the file's own, not a frame's).
    first, last = tum.frames_span
    flips = sorted(rng.randrange(first, last) for _ in range(30))
    got = check(tum, flips, tmp_path)
    assert got.dropped > 0
    assert got.damage


@pytest.mark.shared_data
def test_a_damaged_record_header_is_passed_over(tum: Original, tmp_path: Path) -> None:
    """A flipped record type or length: reading goes on at the next whole chunk."""
    depth = sorted(tum.at[fmt.TOPIC_DEPTH].values())
    flips = [depth[10], depth[40] + 3, tum.extent[depth[60]] + 4]  # type, length, message index
    got = check(tum, flips, tmp_path)
    assert got.dropped == 2


def test_a_damaged_rig_keeps_each_cameras_frames(tmp_path: Path) -> None:
    """Camera 'a' loses the frame whose depth chunk is damaged; camera 'b' keeps every frame,
    those whose color decodes from a damaged packet without color."""
    frames = small_frames(8)
    specs = [CameraSpec("a", CAMERA, 5000.0, color=None), CameraSpec("b", CAMERA, 5000.0)]
    path = tmp_path / "rig.pcdc"
    with pcdcodec.open(path, "w", cameras=specs) as w:
        for color, depth, ts in frames:
            w.write("a", None, depth, ts)
            w.write("b", color, depth, ts + 1000)
    with pcdcodec.open(path) as rig:
        a, b = rig.frames("a"), rig.frames("b")
        depth_at = sorted(a.index.offsets[fmt.TOPIC_DEPTH])
        color_at = sorted(b.index.offsets[fmt.TOPIC_COLOR])
        colors = [f.color for f in b]
    data = bytearray(path.read_bytes())
    data[depth_at[4] + 200] ^= 0x20
    data[color_at[2] + 200] ^= 0x20
    damaged = tmp_path / "damaged.pcdc"
    damaged.write_bytes(bytes(data))
    got = pcdcodec.recover(damaged, tmp_path / "back.pcdc")
    assert got == 15
    assert [(loss.camera, loss.stream, loss.frames) for loss in got.lost] == [
        ("a", "frame", (4,)),
        ("b", "color", (2,)),
        ("b", "color", (3, 4, 5, 6, 7)),
    ]
    with pcdcodec.open(tmp_path / "back.pcdc") as rig:
        assert rig.verify().ok
        a, b = rig.frames("a"), rig.frames("b")
        assert [f.timestamp_ns for f in a] == [ts for i, (_, _, ts) in enumerate(frames) if i != 4]
        assert b.color_missing == [2, 3, 4, 5, 6, 7]
        for i, f in enumerate(b):
            np.testing.assert_array_equal(f.depth, frames[i][1])
            if i < 2:
                np.testing.assert_array_equal(f.color, colors[i])
            else:
                assert f.color is None


def recovered_without_color(root: Path) -> Path:
    """A 6-frame recording whose color from frame 3 on was lost to a flipped byte, recovered
    into ``root / "back.pcdc"``: frames 3, 4 and 5 read with ``color`` None."""
    path = root / "one.pcdc"
    with pcdcodec.open(path, "w", intrinsics=CAMERA, depth_scale=5000.0) as w:
        for color, depth, ts in small_frames(6):
            w.write(color, depth, ts)
    with pcdcodec.open(path) as rec:
        color_at = sorted(rec.index.offsets[fmt.TOPIC_COLOR])
    data = bytearray(path.read_bytes())
    data[color_at[3] + 200] ^= 0x20
    damaged = root / "damaged.pcdc"
    damaged.write_bytes(bytes(data))
    back = root / "back.pcdc"
    got = pcdcodec.recover(damaged, back)
    assert got == 6
    assert got.color_missing == 3
    return back


def test_frames_without_color_are_said_and_not_written_again_as_colored(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    back = recovered_without_color(tmp_path)
    assert main(["info", str(back)]) == 0
    assert "3 frame(s) kept by `pcdcodec recover` without their color" in capsys.readouterr().out
    with pytest.raises(pcdcodec.DecodeError, match=r"frames 3, 4, 5\): they cannot be written"):
        pcdcodec.encode(back, tmp_path / "again.pcdc")


def test_a_file_written_before_digests_loses_color_from_any_damage_on(tmp_path: Path) -> None:
    """Without digests nothing says what a damaged chunk held: the color stream is taken as
    broken from there to the next keyframe, and every frame keeps its depth."""
    from pcdcodec.recording.rewrite import rewrite

    path = tmp_path / "new.pcdc"
    frames = small_frames(6)
    with pcdcodec.open(path, "w", intrinsics=CAMERA, depth_scale=5000.0) as w:
        for color, depth, ts in frames:
            w.write(color, depth, ts)
    old = tmp_path / "old.pcdc"
    rewrite(path, old, strip_integrity=True)
    with pcdcodec.open(old) as rec:
        assert not rec.integrity
        depth_at = sorted(rec.index.offsets[fmt.TOPIC_DEPTH])
        colors = [f.color for f in rec]
    data = bytearray(old.read_bytes())
    data[depth_at[2] + 200] ^= 0x20
    damaged = tmp_path / "damaged.pcdc"
    damaged.write_bytes(bytes(data))
    got = pcdcodec.recover(damaged, tmp_path / "back.pcdc")
    assert got == 5
    assert [(loss.stream, loss.frames) for loss in got.lost] == [
        ("frame", (2,)),
        ("color", (3, 4, 5)),
    ]
    with pcdcodec.open(tmp_path / "back.pcdc") as rec:
        assert rec.verify().ok
        kept = [0, 1, 3, 4, 5]
        assert rec.timestamps.tolist() == [frames[i][2] for i in kept]
        for k, f in zip(kept, rec, strict=True):
            np.testing.assert_array_equal(f.depth, frames[k][1])
            if k < 2:
                np.testing.assert_array_equal(f.color, colors[k])
            else:
                assert f.color is None
