"""pcdcodec archive: segments joined into valid recordings, resumable runs, and every fault."""

from __future__ import annotations

import errno
import importlib.util
import itertools
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import archive as archive_module
from pcdcodec.archive import LOCK, MANIFEST, PARTS, archive, discover, tasks
from pcdcodec.archive import run as archive_run
from pcdcodec.datasets import RGBDSequence, load_sample, write_folder
from pcdcodec.recording import _index as fmt
from pcdcodec.recording.join import join

from .conftest import REPO, SAMPLE

pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def sample() -> RGBDSequence:
    return load_sample()


def make_input(dst: Path, first: int = 0, count: int = 15) -> Path:
    """A TUM folder holding ``count`` frames of the bundled sample from frame ``first``."""
    rows = (SAMPLE / "associations.txt").read_text().splitlines()[first : first + count]
    (dst / "rgb").mkdir(parents=True)
    (dst / "depth").mkdir()
    for row in rows:
        _, rgb, _, depth = row.split()
        shutil.copyfile(SAMPLE / rgb, dst / rgb)
        shutil.copyfile(SAMPLE / depth, dst / depth)
    (dst / "associations.txt").write_text("\n".join(rows) + "\n")
    for name in ("rgb.txt", "depth.txt"):
        (dst / name).write_text("")
    shutil.copyfile(SAMPLE / "camera.json", dst / "camera.json")
    return dst


def assert_same_as_source(output: Path, source: Path) -> None:
    """The recording checks of tests/test_recording.py, against the source folder."""
    frames = list(pcdcodec.open_source(source))
    with pcdcodec.open(output) as rec:
        assert rec.indexed
        assert rec.verify().ok
        assert len(rec) == len(frames)
        np.testing.assert_array_equal(rec.timestamps, [f.timestamp_ns for f in frames])
        sequential = []
        for frame, original in zip(rec, frames, strict=True):
            np.testing.assert_array_equal(frame.depth, original.depth)
            assert frame.depth.dtype == original.depth.dtype
            assert frame.color is not None
            assert pcdcodec.metrics.psnr(frame.color, original.color) > 30
            sequential.append(frame.color.copy())
    with pcdcodec.open(output) as rec:  # random access gives what sequential decoding gave
        for i in np.random.default_rng(0).permutation(len(frames)).tolist():
            np.testing.assert_array_equal(rec[i].color, sequential[i])
            np.testing.assert_array_equal(rec[i].depth, frames[i].depth)


def partials(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if ".partial-" in p.name]


def manifest(out: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / MANIFEST).read_text())["inputs"]
    return data


# -- join ---------------------------------------------------------------------------------------


def write_parts(tmp: Path, seq: RGBDSequence, bounds: list[int], **options: Any) -> list[Path]:
    tmp.mkdir(exist_ok=True)
    parts = []
    for i, (a, b) in enumerate(itertools.pairwise(bounds)):
        path = tmp / f"part{i}.pcdc"
        with pcdcodec.open(
            path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, **options
        ) as w:
            w.write_frames(seq.frames[a:b])
        parts.append(path)
    return parts


@pytest.mark.parametrize(
    "color", [pcdcodec.get_codec("h264", bframes=2, gop=4), pcdcodec.get_codec("ffv1")]
)
def test_join_reads_like_one_writer(tmp_path: Path, sample: RGBDSequence, color: Any) -> None:
    parts = write_parts(tmp_path, sample, [0, 4, 7, 9], color=color, metadata={"site": "lab"})
    alone = []
    for p in parts:
        with pcdcodec.open(p) as rec:
            alone += [f.color.copy() for f in rec]  # type: ignore[union-attr]
    out = tmp_path / "joined.pcdc"
    assert join(parts, out) == 9
    with pcdcodec.open(out) as rec:
        assert rec.indexed
        assert len(rec) == 9
        assert rec.metadata == {"site": "lab"}
        assert rec.codecs["color"] == color.stored_config()
        np.testing.assert_array_equal(rec.timestamps, [f.timestamp_ns for f in sample][:9])
        for frame, original, color_alone in zip(rec, sample.frames[:9], alone, strict=True):
            np.testing.assert_array_equal(frame.depth, original.depth)
            # Decoding straight through the joins gives each segment's own decode.
            np.testing.assert_array_equal(frame.color, color_alone)
        assert {0, 4, 7} <= set(rec._keyframes)
        report = rec.verify()  # every checksum, and a full scan against the index
        assert report.ok, report.errors
        for i in (8, 5, 4, 0, 7, 3):
            np.testing.assert_array_equal(rec[i].color, alone[i])
    # One metadata record, the calibration once, sequence numbers that continue.
    from mcap.reader import make_reader

    with out.open("rb") as f:
        reader = make_reader(f)
        assert [m.name for m in reader.iter_metadata()] == [
            fmt.METADATA_NAME,
            "user",
            fmt.SEAL_NAME,
        ]
        seqs: dict[str, list[int]] = {}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            seqs.setdefault(channel.topic, []).append(message.sequence)
    assert seqs[fmt.TOPIC_CALIBRATION] == [0]
    assert seqs[fmt.TOPIC_DEPTH] == list(range(9))
    assert seqs[fmt.TOPIC_COLOR] == list(range(9))
    assert seqs[fmt.TOPIC_FRAME_DIGEST] == list(range(9))
    assert {0, 4, 7} <= set(seqs[fmt.TOPIC_KEYFRAMES]) <= set(range(9))


def test_join_refuses_parts_that_do_not_fit(tmp_path: Path, sample: RGBDSequence) -> None:
    a = write_parts(tmp_path / "a", sample, [0, 5, 10])
    (tmp_path / "b").mkdir()
    b = write_parts(tmp_path / "b", sample, [10, 15], color=pcdcodec.get_codec("h264", crf=30))
    with pytest.raises(pcdcodec.InputError, match=r"cannot follow.*differs"):
        join([a[0], b[0]], tmp_path / "x.pcdc")
    with pytest.raises(pcdcodec.InputError, match="time order"):
        join([a[1], a[0]], tmp_path / "x.pcdc")
    unfinished = tmp_path / "cut.pcdc"
    unfinished.write_bytes(a[0].read_bytes()[:-200])
    with pytest.raises(pcdcodec.DecodeError, match="recover"):
        join([a[0], unfinished], tmp_path / "x.pcdc")
    with pytest.raises(pcdcodec.InputError, match="already exists"):
        join(a, a[0])
    assert not (tmp_path / "x.pcdc").exists()
    assert not partials(tmp_path)


# -- archive runs -------------------------------------------------------------------------------


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    """An archive: lab/day1/{a,b} and lab/c, six frames each."""
    src = tmp_path / "lab"
    make_input(src / "day1" / "a", 0, 6)
    make_input(src / "day1" / "b", 5, 6)
    make_input(src / "c", 9, 6)
    (src / "notes.txt").write_text("not an input")
    return src


def test_archive_mirrors_verifies_and_skips_on_rerun(tmp_path: Path, tree: Path) -> None:
    out = tmp_path / "out"
    messages: list[str] = []
    seen: list[tuple[int, int]] = []
    summary = archive(
        [tree],
        out,
        workers=2,
        processes=False,
        segment_frames=4,
        verify=True,
        progress=lambda done, total: seen.append((done, total)),
        log=messages.append,
    )
    assert summary.ok, summary.to_text()
    # Progress counts source bytes, up to all of them.
    assert seen[-1][0] == seen[-1][1] == summary.bytes_in
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)
    assert messages[0].startswith("dashboard: ")
    if importlib.util.find_spec("bokeh") is not None:
        assert summary.dashboard is not None
        assert summary.dashboard.startswith("http://")
        assert summary.dashboard in messages[0]
    assert sorted(Path(i.output).relative_to(out).as_posix() for i in summary.items) == [
        "lab/c.pcdc",
        "lab/day1/a.pcdc",
        "lab/day1/b.pcdc",
    ]
    assert {i.state for i in summary.items} == {"verified"}
    assert all(i.segments == 2 and i.frames == 6 for i in summary.items)
    assert summary.bytes_out == sum(Path(i.output).stat().st_size for i in summary.items)
    assert summary.ratio is not None
    assert summary.ratio > 3
    assert summary.throughput > 0
    assert summary.frames == 18
    for name in ("day1/a", "day1/b", "c"):
        assert_same_as_source(out / "lab" / f"{name}.pcdc", tree / name)
    entries = manifest(out)
    assert set(entries) == {"lab/c.pcdc", "lab/day1/a.pcdc", "lab/day1/b.pcdc"}
    for entry in entries.values():
        assert entry["state"] == "verified"
        assert entry["hash"].startswith("blake2b:")
        assert entry["size"] > 0
        assert entry["segments"] == [[0, 3], [3, 6]]
    assert not partials(out)
    assert not (out / PARTS).exists()
    text = summary.to_text()
    assert "3 written" in text
    assert "MB/s" in text
    assert "frames/s" in text

    before = {p: p.stat().st_mtime_ns for p in out.rglob("*.pcdc")}
    again = archive([tree], out, workers=1, processes=False, segment_frames=4, progress=False)
    assert [i.state for i in again.items] == ["skipped"] * 3
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.pcdc")} == before

    # A changed source is encoded again; the others stay skipped.
    shutil.rmtree(tree / "c")
    make_input(tree / "c", 2, 5)
    third = archive([tree], out, workers=1, processes=False, segment_frames=4, progress=False)
    assert sorted(i.state for i in third.items) == ["done", "skipped", "skipped"]
    assert_same_as_source(out / "lab" / "c.pcdc", tree / "c")


def test_delete_source_only_after_verification(tmp_path: Path) -> None:
    a = make_input(tmp_path / "a", 0, 4)
    b = make_input(tmp_path / "b", 0, 4)
    kept = {p.relative_to(b): p.read_bytes() for p in b.rglob("*") if p.is_file()}
    (b / "depth" / sorted(os.listdir(b / "depth"))[2]).write_bytes(b"\x89PNG broken")
    out = tmp_path / "out"
    summary = archive(
        [a, b], out, workers=1, processes=False, delete_source_after_verify=True, progress=False
    )
    states = {Path(i.source).name: i.state for i in summary.items}
    assert states == {"a": "source-deleted", "b": "failed"}
    assert not a.exists()
    assert b.exists()
    assert len(kept) == len([p for p in b.rglob("*") if p.is_file()])
    assert manifest(out)["a.pcdc"]["state"] == "source-deleted"
    with pcdcodec.open(out / "a.pcdc") as rec:
        assert len(rec) == 4


def test_verification_catches_an_output_that_differs(tmp_path: Path) -> None:
    src = make_input(tmp_path / "a", 0, 5)
    out = tmp_path / "out"
    assert archive([src], out, workers=1, processes=False, progress=False).ok
    output = str(out / "a.pcdc")
    with pcdcodec.open(output) as rec:
        colors = [tasks._digest(f.color) for f in rec]
    assert tasks._verify(str(src), {}, output, colors) == {"frames": 5}
    wrong = [colors[0], "0" * 32, *colors[2:]]
    with pytest.raises(pcdcodec.VerificationError, match="frame 1 color differs"):
        tasks._verify(str(src), {}, output, wrong)
    depth = sorted((src / "depth").iterdir())
    shutil.copyfile(sorted((SAMPLE / "depth").iterdir())[10], depth[3])
    with pytest.raises(pcdcodec.VerificationError, match="frame 3 depth differs"):
        tasks._verify(str(src), {}, output, colors)
    shorter = make_input(tmp_path / "b", 0, 4)
    with pytest.raises(pcdcodec.VerificationError, match="more frames than the source"):
        tasks._verify(str(shorter), {}, output, None)


def test_corrupt_input_is_reported_and_the_others_finish(tmp_path: Path) -> None:
    good = make_input(tmp_path / "src" / "good", 0, 5)
    bad = make_input(tmp_path / "src" / "bad", 0, 8)
    broken = sorted((bad / "depth").iterdir())[6]
    broken.write_bytes(broken.read_bytes()[:100])
    out = tmp_path / "out"
    summary = archive(
        [tmp_path / "src"], out, workers=2, processes=False, segment_frames=3, progress=False
    )
    assert not summary.ok
    assert [Path(i.source).name for i in summary.failed] == ["bad"]
    assert broken.name in (summary.failed[0].error or "")
    assert f"FAILED {bad}" in summary.to_text()
    assert_same_as_source(out / "src" / "good.pcdc", good)
    assert not (out / "src" / "bad.pcdc").exists()
    assert not partials(out)
    assert not (out / PARTS).exists()
    assert manifest(out)["src/bad.pcdc"]["state"] == "failed"
    assert broken.name in manifest(out)["src/bad.pcdc"]["error"]


def test_cli_archive(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from pcdcodec.cli import main

    src = make_input(tmp_path / "take1", 0, 4)
    out = tmp_path / "out"
    args = ["archive", str(src), "-o", str(out), "--workers", "1", "--threads", "-q"]
    args += ["--depth", "zstd"]
    assert main([*args, "--verify", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["done"] == 1
    assert result["failed"] == 0
    assert result["frames"] == 4
    assert result["items"][0]["state"] == "verified"
    with pcdcodec.open(out / "take1.pcdc") as rec:
        assert rec.codecs["depth"]["id"] == "zstd"
    assert main(args) == 0
    assert "1 already done" in capsys.readouterr().out
    assert main(["archive", str(src), str(tmp_path / "missing"), "-o", str(out), "-q"]) == 1
    assert "does not exist" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["archive", str(src), "-o", str(out), "--scheduler", "x", "--workers", "2"])
    assert exit_info.value.code == 2


# -- faults -------------------------------------------------------------------------------------


def test_two_runs_on_one_output_are_refused(tmp_path: Path) -> None:
    src = make_input(tmp_path / "a", 0, 3)
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\n"
            "from pathlib import Path\n"
            "from pcdcodec.archive.manifest import _Lock\n"
            "with _Lock(Path(sys.argv[1])):\n"
            "    print('locked', flush=True)\n"
            "    time.sleep(60)\n",
            str(out),
        ],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    try:
        assert holder.stdout is not None
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(pcdcodec.ArchiveLockedError, match=f"pid {holder.pid}"):
            archive([src], out, workers=1, processes=False, progress=False)
        assert not (out / "a.pcdc").exists()
    finally:
        holder.kill()
        holder.wait()
    # The lock dies with its holder: no stale lock to clear by hand.
    assert archive([src], out, workers=1, processes=False, progress=False).ok
    assert (out / LOCK).exists()


def _no_space(*args: Any, **kwargs: Any) -> Any:
    raise OSError(errno.ENOSPC, "No space left on device")


def test_full_disk_stops_cleanly_and_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in "abc":
        make_input(tmp_path / "src" / name, 0, 4)
    out = tmp_path / "out"
    from pcdcodec.recording.writer import RecordingWriter

    original = RecordingWriter._drain_one
    calls = {"n": 0}

    def filling(self: RecordingWriter) -> None:
        calls["n"] += 1
        if calls["n"] > 6:  # the disk fills up during the second input
            _no_space()
        original(self)

    monkeypatch.setattr(RecordingWriter, "_drain_one", filling)
    summary = archive([tmp_path / "src"], out, workers=1, processes=False, progress=False)
    assert not summary.ok
    assert summary.stopped is not None
    assert "no space left" in summary.stopped
    assert "free space and run again" in summary.stopped
    assert summary.failed
    assert "no space left" in (summary.failed[0].error or "")
    written = sorted(Path(i.output).name for i in summary.items if i.state == "done")
    assert len(written) < 3
    # Nothing half-written under a final name, nor left behind at all.
    assert sorted(p.name for p in out.rglob("*.pcdc") if PARTS not in p.parts) == written
    assert not partials(out)
    assert "stopped: no space left" in summary.to_text()

    monkeypatch.setattr(RecordingWriter, "_drain_one", original)
    again = archive([tmp_path / "src"], out, workers=1, processes=False, progress=False)
    assert again.ok
    assert sorted(i.state for i in again.items) == sorted(
        ["skipped"] * len(written) + ["done"] * (3 - len(written))
    )
    for name in "abc":
        assert_same_as_source(out / "src" / f"{name}.pcdc", tmp_path / "src" / name)


@pytest.fixture
def tiny_disk(tmp_path: Path) -> Iterator[Path]:
    """A 700 KiB tmpfs, where the system lets this process mount one."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if sys.platform != "linux" or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root on Linux")
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=700k", "tmpfs", str(mount)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def test_a_really_full_disk(tmp_path: Path, tiny_disk: Path) -> None:
    src = tmp_path / "src"
    for name in "abcd":
        make_input(src / name, 0, 6)
    summary = archive([src], tiny_disk, workers=1, processes=False, progress=False)
    assert summary.stopped is not None
    assert "no space left" in summary.stopped
    assert not partials(tiny_disk)
    for item in summary.items:
        out = Path(item.output)
        if item.state == "done":
            assert_same_as_source(out, Path(item.source))
        else:
            assert not out.exists()
    assert manifest(tiny_disk)  # the manifest itself survived


def test_worker_killed_mid_task_is_retried_and_exact(tmp_path: Path) -> None:
    inputs = [make_input(tmp_path / "src" / n, 0, 15) for n in ("a", "b")]
    out = tmp_path / "out"
    killed: list[int] = []
    finished = threading.Event()

    def killer() -> None:
        # Kill the first worker seen writing a segment (its pid is in the partial name).
        while not finished.is_set() and not killed:
            for p in partials(out):
                m = re.search(r"\.partial-(\d+)-", p.name)
                if m and int(m.group(1)) != os.getpid():
                    os.kill(int(m.group(1)), signal.SIGKILL)
                    killed.append(int(m.group(1)))
                    break
            time.sleep(0.01)

    thread = threading.Thread(target=killer)
    thread.start()
    try:
        summary = archive(
            [tmp_path / "src"], out, workers=2, verify=True, segment_frames=15, progress=False
        )
    finally:
        finished.set()
        thread.join()
    assert killed, "no worker was caught mid-task"
    assert summary.ok, summary.to_text()
    assert {i.state for i in summary.items} == {"verified"}
    for src in inputs:
        assert_same_as_source(out / "src" / f"{src.name}.pcdc", src)
    assert not partials(out)


# The run stops making progress once the first input is done and the second has two of its
# three segments, so the kill below always lands mid-run, however fast the machine.
_RUN = """
import sys, time
from pcdcodec.archive import archive, run as archive_run
original = archive_run._encode_segment
encoded = []
def held(*args):
    out = original(*args)
    encoded.append(args[2])
    if len(encoded) >= 5:
        time.sleep(600)
    return out
archive_run._encode_segment = held
summary = archive(sys.argv[1:-1], sys.argv[-1], workers=1, processes=False, segment_frames=3,
                  progress=False)
# Never reached while the hold works: say why the run ended.
print(f"the run ended after {len(encoded)} segment(s):", summary.to_text(), file=sys.stderr)
sys.exit(3)
"""


def test_whole_run_killed_then_resumed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    names = ["a", "b", "c", "d", "e"]
    for n in names:
        make_input(tmp_path / "src" / n, 0, 9)
    out = tmp_path / "out"
    log = tmp_path / "run.log"
    with log.open("wb") as err:
        run = subprocess.Popen(
            [sys.executable, "-c", _RUN, str(tmp_path / "src"), str(out)],
            env={**os.environ, "PYTHONPATH": str(REPO)},
            start_new_session=True,
            stderr=err,
        )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and run.poll() is None:
            entries = manifest(out) if (out / MANIFEST).exists() else {}
            parts = list((out / PARTS).rglob("seg-*.pcdc")) if (out / PARTS).exists() else []
            if any(e.get("state") == "done" for e in entries.values()) and parts:
                break
            time.sleep(0.02)
        assert run.poll() is None, (
            f"the run ended (exit {run.returncode}) before it could be killed: "
            + log.read_text(errors="replace")[-3000:]
        )
        os.killpg(run.pid, signal.SIGKILL)
    finally:
        run.wait()
    done_before = {k for k, e in manifest(out).items() if e.get("state") == "done"}
    kept_parts = {p.relative_to(out / PARTS) for p in (out / PARTS).rglob("seg-*.pcdc")}
    assert done_before
    assert kept_parts
    stamps = {k: (out / k).stat().st_mtime_ns for k in done_before}

    encoded: list[tuple[str, int]] = []
    original = archive_run._encode_segment

    def counting(src: str, options: Any, part: str, *rest: Any) -> Any:
        encoded.append((part, rest[0]))
        return original(src, options, part, *rest)

    monkeypatch.setattr(archive_run, "_encode_segment", counting)
    summary = archive([tmp_path / "src"], out, workers=1, processes=False, segment_frames=3)
    assert summary.ok, summary.to_text()
    states = {Path(i.output).relative_to(out).as_posix(): i.state for i in summary.items}
    assert {k for k, s in states.items() if s == "skipped"} == done_before
    assert {k: (out / k).stat().st_mtime_ns for k in done_before} == stamps
    # Segments finished before the kill were not encoded again.
    redone = {Path(p).relative_to(out / PARTS) for p, _ in encoded}
    assert not redone & kept_parts
    for n in names:
        assert_same_as_source(out / "src" / f"{n}.pcdc", tmp_path / "src" / n)
    assert not partials(out)
    assert not (out / PARTS).exists()


def test_import_pcdcodec_does_not_import_dask() -> None:
    code = "import sys, pcdcodec, pcdcodec.archive; print('distributed' in sys.modules)"
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
        check=True,
    )
    assert done.stdout.strip() == "False"


def test_a_pointcloud2_bag_is_archived_and_verified(tmp_path: Path) -> None:
    bag = tmp_path / "lab" / "cloud.bag"
    bag.parent.mkdir()
    pcdcodec.export_bag(make_input(tmp_path / "seq", 0, 2), bag, images=False, cloud=True)
    out = tmp_path / "out"
    summary = archive([tmp_path / "lab"], out, workers=1, processes=False, verify=True)
    assert summary.ok, summary.to_text()
    assert summary.items[0].state == "verified"
    assert summary.ratio is not None
    assert summary.ratio > 20  # 32 bytes per point in, a video and a depth image out
    output = out / "lab" / "cloud.pcdc"
    assert_same_as_source(output, bag)
    with pcdcodec.open_source(bag) as source, pcdcodec.open(output) as rec:
        # The recording keeps the reader's depth scale and dtype (checked bit-exact above).
        assert rec.depth_scale == source.depth_scale
        assert rec.intrinsics == source.intrinsics


def test_verify_holds_a_bounded_depth_codec_to_its_bound(tmp_path: Path) -> None:
    src = make_input(tmp_path / "a", 0, 4)
    out = tmp_path / "out"
    bounded = {"id": "depthac", "max_rel_error": 0.01}
    summary = archive(
        [src], out, workers=1, processes=False, progress=False, verify=True, depth=bounded
    )
    assert summary.ok, [i.error for i in summary.items]
    with pcdcodec.open(out / "a.pcdc") as rec:
        assert rec.codecs["depth"]["max_rel_error"] == 0.01
    bound = tasks._depth_bound(bounded)
    depth = load_sample(max_frames=1)[0].depth
    valid = depth > 0
    near = depth.copy()
    near[valid] = depth[valid] + (depth[valid] // 100)  # 1 %: within the bound
    assert tasks._depth_mismatch(near, depth, bound) == ""
    far = near.copy()
    far[valid] += 2
    assert "more than the codec's bound" in tasks._depth_mismatch(far, depth, bound)
    holed = near.copy()
    holed[np.argwhere(valid)[0][0], np.argwhere(valid)[0][1]] = 0
    assert "holes" in tasks._depth_mismatch(holed, depth, bound)
    assert tasks._depth_mismatch(near, depth, None) == "differs from the source"


def test_cli_archive_gives_folders_a_camera(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    src = make_input(tmp_path / "bare", 0, 3)
    (src / "camera.json").unlink()  # a folder that does not say its camera or depth scale
    out = tmp_path / "out"
    args = ["archive", str(src), "-o", str(out), "--workers", "1", "--threads", "-q", "--json"]
    assert main(args) == 1
    capsys.readouterr()
    assert main([*args, "--camera", "tum-fr1"]) == 0
    assert json.loads(capsys.readouterr().out)["frames"] == 3
    with pcdcodec.open(out / "bare.pcdc") as rec:
        assert rec.depth_scale == 5000.0
        assert rec.intrinsics.fx == 517.3  # the fr1 camera's published focal length


def test_verify_at_width_424(tmp_path: Path, sample: RGBDSequence) -> None:
    """RealSense 424x240 and Spot images: rows of 1272 bytes, which video decoders pad."""
    from pcdcodec.cli import main

    frames = [
        pcdcodec.Frame(f.color[:240, :424].copy(), f.depth[:240, :424].copy(), f.timestamp_ns)
        for f in sample.frames[:4]
    ]
    cam = pcdcodec.CameraIntrinsics(424, 240, 300.0, 300.0, 212.0, 120.0)
    src = tmp_path / "rs424"
    write_folder(frames, src, intrinsics=cam, depth_scale=sample.depth_scale)
    out = tmp_path / "out"
    args = ["archive", str(src), "-o", str(out), "--workers", "1", "--threads", "-q"]
    assert main([*args, "--verify", "--json"]) == 0
    with pcdcodec.open(out / "rs424.pcdc") as rec:
        color = rec[1].color
    assert color is not None
    assert color.shape == (240, 424, 3)
    assert color.flags["C_CONTIGUOUS"]  # decoders give plain images, not views of padded rows
    # The digest is of the values, not of how they lie in memory.
    wide = np.zeros((240, 432, 3), np.uint8)
    wide[:, :424] = color
    view = wide[:, :424]
    assert not view.flags["C_CONTIGUOUS"]
    assert tasks._digest(view) == tasks._digest(color)
    assert tasks._digest(color) != tasks._digest(color.reshape(424, 240, 3))


def test_summary_sizes_follow_symlinks(tmp_path: Path) -> None:
    real = make_input(tmp_path / "real", 0, 3)
    size = sum(f.stat().st_size for f in real.rglob("*") if f.is_file())
    # A dataset assembled from links: linked folders, a linked file, a dangling link.
    linked = tmp_path / "src" / "linked"
    linked.mkdir(parents=True)
    for entry in real.iterdir():
        (linked / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    (linked / "notes.txt").symlink_to(tmp_path / "gone.txt")
    assert discover._stat(linked)[0] == size
    out = tmp_path / "out"
    summary = archive([linked], out, workers=1, processes=False, progress=False)
    assert summary.ok
    (item,) = summary.items
    assert item.bytes_in == size
    assert summary.bytes_in == size
    assert summary.ratio is not None
    assert summary.ratio == pytest.approx(size / summary.bytes_out)
    text = summary.to_text()
    assert f"{size / 1e6:.1f} MB in" in text
    assert f"(ratio {summary.ratio:.1f}x)" in text
    assert "ratio 0.0x" not in text
    assert manifest(out)["linked.pcdc"]["size"] == size
    # The hash sees the files behind the links: a changed linked image is a changed input.
    assert discover._hash(linked) == discover._hash(real)


def test_summary_of_an_input_of_unknown_size(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    src = make_input(tmp_path / "a", 0, 2)
    real_stat = os.stat

    def no_access(path: Any, *args: Any, **kwargs: Any) -> Any:
        if Path(path).name == "associations.txt":
            raise PermissionError(13, "Permission denied", str(path))
        return real_stat(path, *args, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(discover.os, "stat", no_access)
        size, mtime = discover._stat(src)
    assert size is None
    assert mtime > 0
    item = archive_module.ArchiveItem(str(src), "a.pcdc", "done", None, 12_345, 2)
    summary = archive_module.ArchiveSummary([item], seconds=1.0, workers=1)
    assert summary.bytes_in is None
    assert summary.ratio is None
    assert summary.throughput is None
    text = summary.to_text()
    assert "? MB (an input's size is unknown) in, 0.0 MB out (ratio -)" in text
    assert "0.0x" not in text
    assert summary.to_dict()["bytes_in"] is None


def _seven_scenes_like(dst: Path, count: int = 3) -> Path:
    """Sample frames laid out as 7-Scenes ships them: rgb/frame-NNNNNN.color.png,
    depth/frame-NNNNNN.depth.png and camera-intrinsics.txt, no depth scale written down."""
    rows = (SAMPLE / "associations.txt").read_text().splitlines()[:count]
    (dst / "rgb").mkdir(parents=True)
    (dst / "depth").mkdir()
    for i, row in enumerate(rows):
        _, rgb, _, depth = row.split()
        shutil.copyfile(SAMPLE / rgb, dst / "rgb" / f"frame-{i:06d}.color.png")
        shutil.copyfile(SAMPLE / depth, dst / "depth" / f"frame-{i:06d}.depth.png")
    (dst / "camera-intrinsics.txt").write_text("585 0 320\n0 585 240\n0 0 1\n")
    return dst


def test_cli_archive_camera_fills_in_only_what_inputs_lack(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    src = tmp_path / "src"
    kitchen = _seven_scenes_like(src / "kitchen")
    office = make_input(src / "office", 0, 3)  # an intrinsics file and a scale-only camera.json
    (office / "camera.json").write_text('{"depth_scale": 1000}')
    (office / "intrinsics.K.txt").write_text("615 0 320\n0 616 240\n0 0 1\n")
    bare = make_input(src / "bare", 0, 3)
    (bare / "camera.json").unlink()  # says nothing: the command line fills in
    out = tmp_path / "out"
    args = ["archive", str(src), "-o", str(out), "--workers", "1", "--threads", "-q"]
    assert main([*args, "--camera", "tum-ros", "--verify", "--json"]) == 0
    captured = capsys.readouterr()
    result = json.loads(captured.out)
    assert result["failed"] == 0
    items = {Path(i["source"]).name: i for i in result["items"]}
    expected = {
        "kitchen": (585.0, 585.0, 1000.0, "camera-intrinsics.txt", "7-Scenes dataset"),
        "office": (615.0, 616.0, 1000.0, "intrinsics.K.txt", "camera.json"),
        "bare": (525.0, 525.0, 5000.0, "--camera tum-ros", "--camera tum-ros"),
    }
    for name, (fx, fy, scale, camera_from, scale_from) in expected.items():
        with pcdcodec.open(out / "src" / f"{name}.pcdc") as rec:
            assert (rec.intrinsics.fx, rec.intrinsics.fy, rec.depth_scale) == (fx, fy, scale)
        item = items[name]
        assert item["state"] == "verified"
        assert (item["camera"]["fx"], item["depth_scale"]) == (fx, scale)
        assert (item["camera_from"], item["depth_scale_from"]) == (camera_from, scale_from)
    # The preset contradicts the two inputs that carry their own camera and scale: said.
    assert len(items["kitchen"]["notes"]) == 2
    assert "the input's is used" in items["office"]["notes"][0]
    assert items["bare"]["notes"] == []
    assert f"warning: {kitchen}: --camera tum-ros camera" in captured.err
    assert f"warning: {office}: --camera tum-ros depth scale 5000" in captured.err
    # The text summary lists each input's camera, scale and their origins, and the notes.
    shutil.rmtree(out)
    assert main([*args, "--camera", "tum-ros"]) == 0
    text = capsys.readouterr().out
    assert f"{kitchen}: camera 640x480 fx=585" in text
    assert "(from camera-intrinsics.txt), depth scale 1000 (from 7-Scenes dataset)" in text
    assert f"{bare}: camera 640x480 fx=525 fy=525 cx=319.5 cy=239.5 (from --camera tum-ros)" in text
    assert f"NOTE {office}: --camera tum-ros depth scale 5000 differs" in text
    # Rerun: skipped inputs keep their camera in the summary (from the manifest).
    assert main([*args, "--camera", "tum-ros"]) == 0
    assert "(from intrinsics.K.txt), depth scale 1000 (from camera.json)" in capsys.readouterr().out


def test_archive_input_options_and_cli_words(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    a = make_input(tmp_path / "a", 0, 3)
    b = make_input(tmp_path / "b", 0, 3)
    (a / "camera.json").unlink()
    (b / "camera.json").unlink()
    out = tmp_path / "out"
    # One input given its own camera (a preset with its scale), the other none: its error
    # names the command-line flags, not Python keywords.
    args = ["archive", str(a), str(b), "-o", str(out), "--workers", "1", "--threads", "-q"]
    assert main([*args, "--input-camera", f"{a}=7scenes"]) == 1
    text = capsys.readouterr().out
    assert f"FAILED {b}" in text
    assert "--depth-scale" in text
    assert "depth_scale=" not in text
    with pcdcodec.open(out / "a.pcdc") as rec:
        assert (rec.intrinsics.fx, rec.depth_scale) == (585.0, 1000.0)
    both = [*args, "--input-camera", f"{a}=7scenes"]
    assert main([*both, "--input-camera", f"{b}=tum-fr1,depth_scale=1000", "--json"]) == 0
    items = {Path(i["source"]).name: i for i in json.loads(capsys.readouterr().out)["items"]}
    assert (items["a"]["state"], items["b"]["camera_from"]) == ("skipped", "given")
    with pcdcodec.open(out / "b.pcdc") as rec:
        assert (rec.intrinsics.fx, rec.depth_scale) == (517.3, 1000.0)
    # No camera at all: the hint names the flags.
    (a / "camera.json").write_text('{"depth_scale": 1000}')
    c = tmp_path / "c"
    shutil.copytree(a, c)
    assert (
        main(["archive", str(c), "-o", str(tmp_path / "o2"), "--workers", "1", "--threads", "-q"])
        == 1
    )
    text = capsys.readouterr().out
    assert "does not say its camera intrinsics; pass --camera NAME or --intrinsics FILE" in text
    assert "source_options" not in text
    assert "camera=" not in text
    with pytest.raises(pcdcodec.InputError, match="not one of the inputs"):
        archive([a], tmp_path / "o3", input_options={tmp_path / "zz": {}}, progress=False)


def test_cli_archive_input_camera_bare_matrix_for_a_bag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--input-camera BAG=K.txt`` with a bare 3x3 matrix: the bag's depth gives the size, as
    a folder's does (it used to fail with "intrinsics dict must be a mapping, got str")."""
    from pcdcodec.cli import main

    from .test_rosbag import _image, _small, _store, write_bag

    store = _store(False)
    frames = _small(2)
    messages = [
        ("/cam/depth/image_raw", 10**9 + i, _image(store, False, 10**9 + i, d, "16UC1"))
        for i, (_, d) in enumerate(frames)
    ]
    (tmp_path / "in").mkdir()
    bag = write_bag(tmp_path / "in" / "cam.bag", messages, store=store)
    k = tmp_path / "K.txt"
    k.write_text("150 0 80\n0 151 60\n0 0 1\n")
    out = tmp_path / "out"
    args = ["archive", str(bag), "-o", str(out), "--workers", "1", "--threads", "-q"]
    assert main([*args, "--input-camera", f"{bag}={k},depth_scale=5000", "--json"]) == 0
    item = json.loads(capsys.readouterr().out)["items"][0]
    assert item["error"] is None
    with pcdcodec.open(out / "cam.pcdc") as rec:
        cam = rec.intrinsics
        assert (cam.width, cam.height, cam.fx, cam.fy) == (160, 120, 150, 151)
        assert rec.depth_scale == 5000


@pytest.mark.parametrize("scale", ["x", [1000], float("inf"), float("nan"), 0, True])
def test_archive_default_depth_scale_must_be_a_positive_number(tmp_path: Path, scale: Any) -> None:
    """A default depth scale that is no number raised ValueError/TypeError; an infinite one was
    taken (and compared with every input's)."""
    a = make_input(tmp_path / "a", 0, 2)
    with pytest.raises(pcdcodec.InputError, match="depth_scale must be a positive finite number"):
        archive([a], tmp_path / "out", source_options={"depth_scale": scale}, progress=False)


def test_cli_archive_intrinsics_bare_matrix_says_what_to_do(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``archive --intrinsics K.txt`` with a bare matrix: the error names the flag and the ways
    that work, not "give width and height", which no archive flag can."""
    from pcdcodec.cli import main

    a = make_input(tmp_path / "a", 0, 2)
    k = tmp_path / "K.txt"
    k.write_text("500 0 320\n0 500 240\n0 0 1\n")
    args = ["archive", str(a), "-o", str(tmp_path / "out"), "-q", "--intrinsics", str(k)]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "give width and height" not in err
    assert f"--intrinsics {str(k)!r} is a camera matrix without the image size" in err
    assert f"--input-camera INPUT={k}" in err
    # A file that is no camera keeps its own error.
    k.write_text("not a camera\n")
    assert main(args) == 1
    assert "without the image size" not in capsys.readouterr().err


def test_a_folder_of_bags_with_a_depth_named_image_is_searched(tmp_path: Path) -> None:
    """runs/ holding bags and a depth_preview.png: the bags are the inputs. The folder was
    taken as a one-frame depth-only image folder, and the bags in it were never archived."""
    import imagecodecs

    from pcdcodec.archive import find_inputs
    from pcdcodec.sources.base import detect_kind

    from .test_rosbag import _image, _small, _store, write_bag

    store = _store(False)
    runs = tmp_path / "runs"
    runs.mkdir()
    frames = _small(1)
    for name in ("a.bag", "b.bag"):
        msg = _image(store, False, 10**9, frames[0][1], "16UC1")
        write_bag(runs / name, [("/cam/depth/image_raw", 10**9, msg)], store=store)
    (runs / "depth_preview.png").write_bytes(imagecodecs.png_encode(frames[0][1]))
    assert detect_kind(runs) is None
    found = find_inputs([runs])
    assert [(p.name, out) for p, out in found] == [
        ("a.bag", "runs/a.pcdc"),
        ("b.bag", "runs/b.pcdc"),
    ]
    # The same with a depth/ folder of previews.
    (runs / "depth_preview.png").unlink()
    (runs / "depth").mkdir()
    (runs / "depth" / "0000.png").write_bytes(imagecodecs.png_encode(frames[0][1]))
    assert detect_kind(runs) is None
    assert [p.name for p, _ in find_inputs([runs])] == ["a.bag", "b.bag"]
    # With color beside depth it is an RGB-D folder whatever else it holds, as before.
    (runs / "rgb").mkdir()
    assert detect_kind(runs) == "folder"
    # Without the bags, depth alone is a depth-only folder.
    shutil.rmtree(runs / "rgb")
    for name in ("a.bag", "b.bag"):
        (runs / name).unlink()
    assert detect_kind(runs) == "folder"


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("{a}=tum-ros,depth_scale=-5", "depth_scale must be a positive number"),
        ("{a}=tum-ros,depth_scale=inf", "depth_scale must be a positive number"),
        ("{a}=tum-ros,depth_scale=abc", "depth_scale must be a positive number"),
        ("{other}=tum-ros", "--input-camera names"),
    ],
)
def test_cli_archive_input_camera_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], spec: str, expected: str
) -> None:
    """A scale that is no positive number is refused before anything is encoded (it was
    listed as the input's scale, then failed); an input not given names the flag, not
    input_options."""
    from pcdcodec.cli import main

    a = make_input(tmp_path / "a", 0, 2)
    arg = spec.format(a=a, other=tmp_path / "other")
    out = tmp_path / "out"
    args = ["archive", str(a), "-o", str(out), "--workers", "1", "--threads", "-q"]
    assert main([*args, "--input-camera", arg]) == 1
    err = capsys.readouterr().err
    assert expected in err
    assert "input_options" not in err
    assert not (out / "a.pcdc").exists()


def test_delete_source_removes_links_not_their_targets(tmp_path: Path) -> None:
    """A linked folder input failed to be deleted ("Cannot call rmtree on a symbolic link"),
    while a linked file had its link removed; both now remove the link and keep the target.
    A source that could not be deleted is said in the text summary (it was in JSON only)."""
    from pcdcodec.archive import ArchiveItem, ArchiveSummary

    real = tmp_path / "real"
    folder = make_input(real / "take", 0, 2)
    links = tmp_path / "links"
    links.mkdir()
    (links / "take").symlink_to(folder, target_is_directory=True)
    summary = archive(
        [links / "take"],
        tmp_path / "out",
        delete_source_after_verify=True,
        workers=1,
        processes=False,
        progress=False,
    )
    (item,) = summary.items
    assert (item.state, item.error) == ("source-deleted", None)
    assert not (links / "take").exists()
    assert not (links / "take").is_symlink()
    assert folder.is_dir()
    assert any(folder.iterdir())  # the linked-to data is kept
    kept = ArchiveItem("a", "out/a.pcdc", "verified", error="verified, but the source could not")
    text = ArchiveSummary([kept], 1.0, 1).to_text()
    assert "WARNING a: verified, but the source could not" in text


def test_local_workers_run_without_the_stack_sampling_profiler() -> None:
    """The workers of a run's own cluster do not sample every thread's stack: in thread workers
    the sampling deadlocked against a garbage collection that freed an FFmpeg object."""
    from pcdcodec.archive.run import _cluster

    with _cluster(None, 1, False) as client:
        sampling = client.run(lambda dask_worker: "profile" in dask_worker.periodic_callbacks)
    assert list(sampling.values()) == [False]
