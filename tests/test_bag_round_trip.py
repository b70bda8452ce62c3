"""The whole bag, there and back: a robot's bag (RealSense camera under realsense-ros names,
aligned and unaligned depth, organized cloud, IMU, odometry, tf, joint states, diagnostics)
encoded and exported again is the original, message by message, where the issue says exact."""

from __future__ import annotations

import collections
import shutil
from pathlib import Path
from typing import Any

import pytest

import pcdcodec
from pcdcodec.bench import robot_bags as rb
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.convert.rosbag import export_bag
from pcdcodec.ros.bagfile import open_reader

SET = "realsense_d435"


def _bag(tmp: Path, kind: str) -> Path:
    seq = SEQUENCES[SET]
    if not seq.present:
        pytest.skip(f"{seq.root} is not present")
    path = tmp / ("in.bag" if kind == "ros1" else "in")
    rb.write_robot_bag(
        path, list(rb.SequenceFrames(SET, 3)), kind=kind, intrinsics=seq.camera,
        depth_scale=seq.depth_scale, seconds=0.6, fps=5.0, cloud_hz=5.0, extras=True,
    )  # fmt: skip
    return path


def _per_topic(messages: list[tuple[str, int, bytes]]) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    for topic, ns, data in messages:
        out[topic].append((ns, data))
    return dict(out)


def _messages(path: Path) -> tuple[list[tuple[str, int, bytes]], dict[str, Any]]:
    reader, tmp = open_reader(path)
    try:
        out = [(c.topic, int(t), bytes(raw)) for c, t, raw in reader.messages()]
        conns = {c.topic: (c.msgtype, c.msgdef.data, c.digest) for c in reader.connections}
    finally:
        reader.close()
        if tmp is not None:
            shutil.rmtree(tmp.name, ignore_errors=True)
    return out, conns


@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite3", "ros2-mcap"])
def test_a_robot_bag_comes_back_message_for_message(kind: str, tmp_path: Path) -> None:
    bag = _bag(tmp_path, kind)
    rec = tmp_path / "x.pcdc"
    pcdcodec.encode(bag, rec, color="ffv1")  # lossless color: every message exact
    back = tmp_path / ("back.bag" if kind == "ros1" else "back")
    summary = export_bag(rec, back)
    assert summary["format"] == ("rosbag1" if kind == "ros1" else "rosbag2")
    assert summary["camera"] == "as recorded"
    want, want_conns = _messages(bag)
    got, got_conns = _messages(back)
    assert got_conns == want_conns  # type, definition, md5sum or type hash of every topic
    # Every message of every topic, its bytes and log time, each topic's in its order (messages
    # of different topics logged at the same nanosecond may come back in another order).
    assert _per_topic(got) == _per_topic(want)
    # The other depth stream and the cloud were packed, not kept raw: the file is small.
    assert rec.stat().st_size * 5 < sum(len(d) for _, _, d in want)


def test_lossy_color_comes_back_in_its_encoding_everything_else_exact(tmp_path: Path) -> None:
    bag = _bag(tmp_path, "ros1")
    rec = tmp_path / "x.pcdc"
    pcdcodec.encode(bag, rec)  # the default color codec: lossy
    back = tmp_path / "back.bag"
    export_bag(rec, back)
    want, _ = _messages(bag)
    got, _ = _messages(back)
    w, g = _per_topic(want), _per_topic(got)
    assert {t: [ns for ns, _ in v] for t, v in g.items()} == {
        t: [ns for ns, _ in v] for t, v in w.items()
    }
    for topic in w:
        pairs = [(a, b) for (_, a), (_, b) in zip(w[topic], g[topic], strict=True)]
        if topic == rb.COLOR:
            for a, b in pairs:
                assert len(a) == len(b)
                header = len(a) - 640 * 480 * 3
                assert a[:header] == b[:header]  # header, size, encoding, step exactly
                diff = sum(x != y for x, y in zip(a[header:], b[header:], strict=True))
                assert diff > 0  # the pixels within the codec's quality, not exact
        else:
            assert all(a == b for a, b in pairs), topic
