"""Kept topics checked end to end like the camera streams: ``verify`` reads every kept message
and compares them with the seal, ``recover`` keeps every message of the chunks whose CRC holds,
and ``join``, re-encoding a recording and ``archive`` keep every kept message once, byte for
byte (``docs/recording.md``)."""

from __future__ import annotations

import collections
import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.cli import main as cli_main
from pcdcodec.errors import DecodeError, IncompleteRecordingWarning, InputError
from pcdcodec.recording import _index, recover
from pcdcodec.recording.join import join
from pcdcodec.ros.kept import KeptMessage, KeptTopic

from .conftest import SEQUENCES

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
SPOT_CAMERA = {"width": 424, "height": 240, "fx": 200.0, "fy": 200.0, "cx": 212.0, "cy": 120.0}
CAM = pcdcodec.CameraIntrinsics(8, 6, 5.0, 5.0, 4.0, 3.0)
MS = 1_000_000

IMU = KeptTopic("/imu", "sensor_msgs/msg/Imu", "ros2msg", "float64 x\n", "cdr", {"q": "1"})
#: One topic from two publishers (a ROS 1 bag's connections): two channels, one name.
TF_A = KeptTopic("/tf", "tf2_msgs/msg/TFMessage", "ros1msg", "x\n", "ros1", {"callerid": "/a"})
TF_B = KeptTopic("/tf", "tf2_msgs/msg/TFMessage", "ros1msg", "x\n", "ros1", {"callerid": "/b"})
TOPICS = [IMU, TF_A, TF_B]


def _messages(start: int = 0) -> list[KeptMessage]:
    """Over 3 MiB of kept messages (several zstd chunks), some sharing a log time."""
    rng = np.random.default_rng(start)
    out = []
    for k in range(1200):
        t = start + 100 + 10 * k
        out.append(KeptMessage(IMU, t, rng.integers(0, 255, 2600, np.uint8).tobytes(), t - 3))
        if k % 7 == 0:
            out.append(KeptMessage(TF_A, t, b"a%d" % k))
            out.append(KeptMessage(TF_B, t, b"b%d" % k))  # same time, other publisher
    return out


def _write(path: Path, messages: list[KeptMessage], *, start: int = 0, close: bool = True) -> Any:
    depth = np.arange(48, dtype=np.uint16).reshape(6, 8)
    w = pcdcodec.open(path, "w", intrinsics=CAM, color=None, kept_topics=TOPICS)
    for k in range(4):
        w.write(None, depth + k, start + MS * (k + 1))
    for m in messages:
        w.write_message(m)
    if close:
        w.close()
    return w


def _as_tuples(messages: Any) -> list[tuple[Any, ...]]:
    return [(m.topic, m.log_time, m.published, bytes(m.data)) for m in messages]


def _read(path: Path) -> list[tuple[Any, ...]]:
    with pcdcodec.open(path) as rec:
        return _as_tuples(rec.kept_messages())


def _chunks(path: Path) -> dict[int, list[tuple[Any, ...]]]:
    """Each kept chunk's byte offset and the messages it holds, in file order."""
    from pcdcodec.recording._kept import kept_channel_ids, kept_offsets

    with open(path, "rb") as f:
        index = _index.load(f)
        channels = kept_channel_ids(index)
        return {
            off: [
                (channels[m.channel_id], m.log_time, m.publish_time, bytes(m.data))
                for m in _index.read_chunk_messages(f, off, what="test")
            ]
            for off in kept_offsets(index)
        }


def _flip(path: Path, at: int, out: Path) -> Path:
    data = bytearray(path.read_bytes())
    data[at] ^= 0x40
    out.write_bytes(bytes(data))
    return out


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[tuple[Any, ...]]]:
    path = tmp_path_factory.mktemp("kept") / "x.pcdc"
    messages = _messages()
    _write(path, messages)
    return path, _as_tuples(messages)


def test_verify_reads_every_kept_message_and_lists_the_topics(
    written: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    path, want = written
    assert _read(path) == want
    with pcdcodec.open(path) as rec:
        report = rec.verify()
    assert report.ok, report.errors
    assert report.kept == {"/imu": 1200, "/tf": 2 * 172}
    assert cli_main(["verify", str(path)]) == 0
    out = capsys.readouterr().out
    assert "/imu  [sensor_msgs/msg/Imu, 1200 msgs]" in out
    assert "/tf   [tf2_msgs/msg/TFMessage, 344 msgs]" in out


def test_verify_names_the_topics_of_a_damaged_kept_chunk(written: Any, tmp_path: Path) -> None:
    path, _ = written
    chunks = _chunks(path)
    assert len(chunks) >= 3
    at, lost = list(chunks.items())[1]
    bad = _flip(path, at + 200, tmp_path / "bad.pcdc")  # inside the compressed data
    with pcdcodec.open(bad) as rec:  # the frames still read
        assert len(rec) == 4
        report = rec.verify()
        with pytest.raises(DecodeError, match=r"bad\.pcdc.*chunk at byte offset"):
            list(rec.kept_messages())
    assert not report.ok
    assert any(f"byte offset {at}" in e and "/imu" in e for e in report.errors), report.errors
    n = sum(1 for m in lost if m[0] is IMU or m[0] == IMU)
    assert f"kept topic /imu: 1200 messages sealed, {1200 - n} read" in report.errors
    assert report.kept["/imu"] == 1200 - n
    assert cli_main(["verify", str(bad)]) == 1


def test_verify_finds_kept_messages_changed_behind_valid_crcs(written: Any, tmp_path: Path) -> None:
    """A kept message changed and its chunk written again with a valid CRC: the seal says so."""
    from pcdcodec.recording import rewrite

    path, _ = written
    contents = rewrite.read(path)
    k = next(i for i, m in enumerate(contents.messages) if m.topic == "/imu")
    changed = contents.messages[k]
    contents.messages[k] = type(changed)(
        changed.topic, changed.log_time, changed.publish_time, changed.sequence, b"changed"
    )
    out = tmp_path / "changed.pcdc"
    rewrite.write(contents, out)
    with pcdcodec.open(out) as rec:
        report = rec.verify()
    assert any("kept messages are not those sealed" in e for e in report.errors), report.errors


def test_recover_keeps_every_message_of_the_chunks_that_hold(written: Any, tmp_path: Path) -> None:
    path, want = written
    chunks = _chunks(path)
    at, lost = list(chunks.items())[1]
    bad = _flip(path, at + 200, tmp_path / "bad.pcdc")
    got = recover(bad, tmp_path / "rec.pcdc")
    assert got.frames == 4
    kept = _read(tmp_path / "rec.pcdc")
    assert kept == [m for off, ms in chunks.items() if off != at for m in ms]
    assert kept == [m for m in want if m not in lost]
    lost_imu = sum(1 for m in lost if m[0].topic == "/imu")
    lost_tf = len(lost) - lost_imu
    lines = got.summary()
    assert (
        f"damage: kept topic /imu: {lost_imu} of 1200 message(s) left out (in damaged chunks)"
        in lines
    )
    assert any(f"kept topic /tf: {lost_tf} of 344" in line for line in lines) == (lost_tf > 0)
    with pcdcodec.open(tmp_path / "rec.pcdc") as rec:
        assert rec.kept_topics == TOPICS  # the same channel descriptions
        assert rec.verify().ok
        assert rec.kept_counts() == {"/imu": 1200 - lost_imu, "/tf": 344 - lost_tf}


def test_recover_of_an_intact_file_keeps_every_kept_message(written: Any, tmp_path: Path) -> None:
    path, want = written
    got = recover(path, tmp_path / "rec.pcdc")
    assert got.frames == 4
    assert got.summary() == []
    assert _read(tmp_path / "rec.pcdc") == want
    # Kept messages stay in compressed chunks of their own.
    assert len(_chunks(tmp_path / "rec.pcdc")) == len(_chunks(path))


@pytest.mark.parametrize("where", ["length", "data"])
def test_recover_passes_over_a_damaged_kept_chunk_of_an_unfinished_file(
    where: str, tmp_path: Path
) -> None:
    """No summary: the scan reads the file from the start, passes over the damaged zstd chunk
    (a damaged length field too, by finding the next whole chunk) and goes on."""
    messages = _messages()
    path = tmp_path / "x.pcdc"
    w = _write(path, messages, close=False)
    w.flush()
    w.abort()  # the writer killed: no seal, no summary; its full chunks are on disk
    chunks = _chunks(path)
    assert len(chunks) >= 2
    at, lost = next(iter(chunks.items()))
    bad = _flip(path, at + (3 if where == "length" else 300), tmp_path / "bad.pcdc")
    got = recover(bad, tmp_path / "rec.pcdc")
    assert got.frames == 4
    written = [m for ms in chunks.values() for m in ms]
    assert _read(tmp_path / "rec.pcdc") == [m for m in written if m not in lost]
    assert any(f"byte offset {at}" in d for d in got.damage), got.damage


def test_recover_of_a_killed_or_cut_writer_keeps_its_written_kept_chunks(tmp_path: Path) -> None:
    messages = _messages()
    path = tmp_path / "x.pcdc"
    w = _write(path, messages, close=False)
    w.flush()
    w.abort()
    chunks = _chunks(path)
    written = [m for ms in chunks.values() for m in ms]
    assert 0 < len(written) < len(messages)
    assert written == _as_tuples(messages)[: len(written)]
    with pytest.warns(IncompleteRecordingWarning), pcdcodec.open(path) as rec:
        assert _as_tuples(rec.kept_messages()) == written  # the unfinished file reads them too
    recover(path, tmp_path / "rec.pcdc")
    assert _read(tmp_path / "rec.pcdc") == written
    # Cut inside the last chunk: the chunks before it are kept.
    last = max(chunks)
    cut = tmp_path / "cut.pcdc"
    cut.write_bytes(path.read_bytes()[: last + 500])
    recover(cut, tmp_path / "rec2.pcdc")
    assert _read(tmp_path / "rec2.pcdc") == [
        m for off, ms in chunks.items() if off < last for m in ms
    ]
    with pcdcodec.open(tmp_path / "rec2.pcdc") as rec:
        assert rec.verify().ok


def test_join_keeps_the_union_of_the_parts_kept_topics(written: Any, tmp_path: Path) -> None:
    path, want = written
    odom = KeptTopic("/odom", "nav_msgs/msg/Odometry", "ros2msg", "float64 y\n", "cdr", {})
    second = tmp_path / "b.pcdc"
    more = [KeptMessage(odom, 10**8 + k, b"o%d" % k) for k in range(5)]
    depth = np.zeros((6, 8), np.uint16)
    with pcdcodec.open(second, "w", intrinsics=CAM, color=None, kept_topics=[IMU, odom]) as w:
        for k in range(3):
            w.write(None, depth + k, 10**8 + MS * (k + 1))
        for m in [*more, KeptMessage(IMU, 10**8, b"late")]:
            w.write_message(m)
    plain = tmp_path / "plain.pcdc"  # keeps nothing: joined all the same
    with pcdcodec.open(plain, "w", intrinsics=CAM, color=None) as w:
        w.write(None, depth, 2 * 10**8)
    assert join([path, second, plain], tmp_path / "j.pcdc") == 8
    with pcdcodec.open(tmp_path / "j.pcdc") as rec:
        assert rec.format_version == 4
        assert rec.kept_topics == [*TOPICS, odom]
        assert rec.verify().ok
    got = _read(tmp_path / "j.pcdc")
    assert got == [*want, *_as_tuples([*more, KeptMessage(IMU, 10**8, b"late")])]


def test_join_refuses_a_topic_kept_with_another_type_or_a_part_whose_kept_messages_changed(
    written: Any, tmp_path: Path
) -> None:
    from pcdcodec.recording import rewrite

    path, _ = written
    other = KeptTopic("/imu", "geometry_msgs/msg/Twist", "ros2msg", "float64 x\n", "cdr", {})
    second = tmp_path / "b.pcdc"
    with pcdcodec.open(second, "w", intrinsics=CAM, color=None, kept_topics=[other]) as w:
        w.write(None, np.zeros((6, 8), np.uint16), 10**8)
        w.write_message(KeptMessage(other, 10**8, b"x"))
    with pytest.raises(InputError, match=r"keep topic '/imu' with another type"):
        join([path, second], tmp_path / "j.pcdc")
    contents = rewrite.read(path)
    k = next(i for i, m in enumerate(contents.messages) if m.topic == "/tf")
    contents.messages[k] = type(contents.messages[k])("/tf", 5, 5, 0, b"moved")
    changed = tmp_path / "changed.pcdc"
    rewrite.write(contents, changed)
    with pytest.raises(DecodeError, match=r"changed\.pcdc.*kept messages are not those sealed"):
        join([changed], tmp_path / "j2.pcdc")
    assert not (tmp_path / "j2.pcdc").exists()


def test_reencoding_a_recording_keeps_its_kept_topics(written: Any, tmp_path: Path) -> None:
    path, want = written
    out = tmp_path / "again.pcdc"
    summary = pcdcodec.encode(path, out, depth="rvl")
    assert {k["name"]: k["messages"] for k in summary.kept} == {"/imu": 1200, "/tf": 344}
    with pcdcodec.open(out) as rec:
        assert rec.kept_topics == TOPICS
        assert rec.codecs["depth"]["id"] == "rvl"  # type: ignore[index]
    assert _read(out) == want
    # Patterns narrow them, and what they leave out is said.
    summary = pcdcodec.encode(path, tmp_path / "imu.pcdc", exclude_topics="/tf")
    assert [k["name"] for k in summary.kept] == ["/imu"]
    assert [k["name"] for k in summary.left_out] == ["/tf"]
    assert _read(tmp_path / "imu.pcdc") == [m for m in want if m[0] is IMU or m[0] == IMU]


# -- real bags -------------------------------------------------------------------------------


def _bag_messages(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    from rosbags.highlevel import AnyReader

    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    with AnyReader([path]) as reader:
        for c, t, raw in reader.messages():
            out[c.topic].append((t, bytes(raw)))
    return dict(out)


def _by_topic(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    for topic, t, _, data in _read(path):
        out[topic.topic].append((t, data))
    return dict(out)


@pytest.fixture(scope="module")
def robot_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from pcdcodec.bench import robot_bags as rb

    seq = SEQUENCES["realsense_d435"]
    if not seq.present:
        pytest.skip(f"{seq.root} is not present")
    path = tmp_path_factory.mktemp("robot") / "robot.bag"
    rb.write_robot_bag(
        path,
        list(rb.SequenceFrames("realsense_d435", 4)),
        intrinsics=seq.camera,
        depth_scale=seq.depth_scale,
        seconds=1.0,
        fps=5.0,  # few frames: the other topics are what is checked
        cloud_hz=5.0,
        extras=True,
    )
    return path


def test_a_robot_bags_kept_topics_survive_recover_join_and_reencoding(
    robot_bag: Path, tmp_path: Path
) -> None:
    from pcdcodec.sources import open_source

    out = tmp_path / "x.pcdc"
    pcdcodec.encode(robot_bag, out, color=None, depth="rvl")
    with open_source(robot_bag) as src:
        kept = {t.topic for t in src.kept_topics() if not t.camera}
    want = {t: v for t, v in _bag_messages(robot_bag).items() if t in kept}
    assert "/camera/imu" in want
    assert "/tf" in want
    assert _by_topic(out) == want
    recover(out, tmp_path / "rec.pcdc")
    assert _by_topic(tmp_path / "rec.pcdc") == want
    pcdcodec.encode(out, tmp_path / "again.pcdc", depth="rvl")
    assert _by_topic(tmp_path / "again.pcdc") == want


def test_spot_bag_kept_topics_survive_join_of_its_parts(tmp_path: Path) -> None:
    bag = BAGS / "spot" / "raw.bag"
    if not bag.exists():
        pytest.skip(f"{bag} is not present")
    out = tmp_path / "x.pcdc"
    pcdcodec.encode(bag, out, intrinsics=SPOT_CAMERA, max_difference=10**12)
    with pcdcodec.open(out) as rec:
        want = _as_tuples(rec.kept_messages())
        kept = rec.kept_topics
    assert want
    again = tmp_path / "again.pcdc"
    pcdcodec.encode(out, again)
    join([again], tmp_path / "j.pcdc")
    with pcdcodec.open(tmp_path / "j.pcdc") as rec:
        assert rec.kept_topics == kept
        assert rec.verify().ok
    assert _read(tmp_path / "j.pcdc") == want


def test_archive_cut_into_segments_keeps_every_kept_message_once(
    robot_bag: Path, tmp_path: Path
) -> None:
    """Each segment keeps the messages logged from its first frame to the next segment's;
    joined, the output holds each of the bag's other messages once, byte for byte."""
    from pcdcodec.archive import archive
    from pcdcodec.sources import open_source

    src = tmp_path / "in" / "robot.bag"
    src.parent.mkdir()
    src.symlink_to(robot_bag)
    out = tmp_path / "out"
    summary = archive(
        [src], out, workers=1, processes=False, segment_frames=2, verify=True,
        progress=False,
    )  # fmt: skip
    assert summary.ok, summary.to_text()
    assert summary.items[0].segments == 3
    with open_source(robot_bag) as source:
        kept = {t.topic for t in source.kept_topics() if not t.camera}
    want = {t: v for t, v in _bag_messages(robot_bag).items() if t in kept}
    got = _by_topic(out / "robot.pcdc")
    assert got == want  # each topic's messages once, in the bag's order
    with pcdcodec.open(out / "robot.pcdc") as rec:
        assert rec.verify().ok


def test_archive_verification_finds_kept_messages_missing() -> None:
    from pcdcodec.archive.checks import check_kept, in_window
    from pcdcodec.errors import VerificationError

    messages = [KeptMessage(IMU, t, b"%d" % t) for t in range(10)]
    assert [m.log_time for m in in_window(iter(messages), (3, 6))] == [3, 4, 5]
    assert check_kept("x", iter(messages), iter(messages)) == 10
    with pytest.raises(VerificationError, match=r"x: the kept messages differ.*1 missing, 1 not"):
        check_kept("x", iter([*messages[:4], messages[3], *messages[5:]]), iter(messages))


def test_a_segment_reads_only_the_kept_messages_of_its_window(robot_bag: Path) -> None:
    from pcdcodec.archive.checks import kept_in
    from pcdcodec.sources import open_source

    with open_source(robot_bag) as source:
        every = _as_tuples(source.kept_messages())
        times = sorted({m[1] for m in every})
        cuts = [None, times[len(times) // 3], times[len(times) // 3] + 1, times[-1], None]
        windows = list(itertools.pairwise(cuts))
        parts = [_as_tuples(kept_in(source, w)) for w in windows]
        # Read through the bag's index with start and stop, not filtered from every message.
        low, high = windows[1]
        assert _as_tuples(source.kept_messages(start=low, stop=high)) == parts[1]
    assert [m for part in parts for m in part] == every
    assert all(parts[k] for k in (0, 1, 3))


def test_verify_lists_a_bags_kept_topics_with_their_types_and_its_camera_messages_apart(
    robot_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    out = tmp_path / "x.pcdc"
    pcdcodec.encode(robot_bag, out, color=None, depth="rvl")
    assert main(["verify", str(out)]) == 0
    said = capsys.readouterr().out
    assert "[?" not in said  # every kept topic listed with its type
    assert "[sensor_msgs/msg/Imu, " in said
    assert "  camera       " in said  # the camera topics' messages, counted apart
    assert "/camera/aligned_depth_to_color/image_raw " not in said.split("camera   ")[0]
