"""Container goldens, reader-chosen settings and the typed open().

A fresh write of the golden frames must have the same container structure as the committed
golden recording and paper-layout export: a change of the on-disk layout then fails here
instead of shipping under the same format version.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.convert.paper import export_paper, import_paper
from pcdcodec.recording import _index as fmt
from pcdcodec.registry import codec_for_reading

from .golden.make_layout_golden import PAPER, RECORDING, SEALED, write_recording
from .golden.make_recording_golden import golden_frames

#: Values that name the writing library's version; everything else must match.
_VOLATILE = {"library"}


def _structure(path: Path) -> dict[str, Any]:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.id: (s.name, s.encoding) for s in summary.schemas.values()}
        channels = {
            c.topic: {
                "encoding": c.message_encoding,
                "schema": schemas.get(c.schema_id),
                "metadata": {
                    k: (v if k != "extradata" else bool(v)) for k, v in sorted(c.metadata.items())
                },
                "messages": summary.statistics.channel_message_counts[c.id]
                if summary.statistics
                else None,
            }
            for c in summary.channels.values()
        }
        metadata = {
            m.name: {k: v for k, v in sorted(m.metadata.items()) if k not in _VOLATILE}
            for m in reader.iter_metadata()
        }
        return {"profile": reader.get_header().profile, "channels": channels, "metadata": metadata}


@pytest.mark.parametrize("golden", [RECORDING, SEALED], ids=["before-seals", "sealed"])
def test_golden_recording_reads_back(golden: Path) -> None:
    with pcdcodec.open(golden) as rec:
        frames = list(rec)
        assert rec.integrity == (golden == SEALED)
        assert rec.verify().ok
    expected = golden_frames()
    assert len(frames) == len(expected)
    for frame, (color, depth, ts) in zip(frames, expected, strict=True):
        assert frame.timestamp_ns == ts
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.color, color)


def test_a_fresh_write_has_the_golden_container_layout(tmp_path: Path) -> None:
    fresh = tmp_path / "fresh.pcdc"
    write_recording(fresh)
    golden, now = _structure(SEALED), _structure(fresh)
    assert now == golden, (
        "the .pcdc container layout changed; if that is intended, raise FORMAT_VERSION (or the "
        "integrity version) and add new goldens with tests/golden/make_layout_golden.py"
    )


def test_color_digests_and_the_seal_only_add_to_the_earlier_layout(tmp_path: Path) -> None:
    """What an earlier reader knows is as before: the same format version, channels and
    metadata, plus one channel, one metadata record and one key it does not read."""
    now, before = _structure(SEALED), _structure(RECORDING)
    assert now["channels"].pop(fmt.TOPIC_FRAME_DIGEST) == {
        "encoding": fmt.ENCODING_FRAME_DIGEST,
        "schema": None,
        "metadata": {},
        "messages": 4,
    }
    seal = now["metadata"].pop(fmt.SEAL_NAME)
    assert seal["frames"] == "4"
    assert seal["tail_packets"] == "0"
    main_now, main_before = now["metadata"]["pcdcodec"], before["metadata"]["pcdcodec"]
    assert main_now.pop(fmt.INTEGRITY_KEY) == "1"
    assert main_now.pop(fmt.DIGEST_KEY) != main_before.pop(fmt.DIGEST_KEY)
    assert main_now["format_version"] == "1"
    assert now == before


def _layout_doc(folder: Path) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((folder / "frames.json").read_text())
    return doc


def test_golden_paper_layout_imports_and_a_fresh_export_matches(tmp_path: Path) -> None:
    back = tmp_path / "back.pcdc"
    assert import_paper(PAPER, back, depth="zstd") == 4
    with pcdcodec.open(back) as rec:
        for frame, (color, depth, ts) in zip(rec, golden_frames(), strict=True):
            assert frame.timestamp_ns == ts
            np.testing.assert_array_equal(frame.depth, depth)
            np.testing.assert_array_equal(frame.color, color)  # ffv1: lossless both ways
    export_paper(RECORDING, tmp_path / "fresh")
    fresh, golden = _layout_doc(tmp_path / "fresh"), _layout_doc(PAPER)
    # Every field of the golden (version 1) layout is written as it was; later exports add the
    # optional fields that keep what a recording holds, which the golden folder, read above,
    # shows are optional on import.
    added = {"metadata", "frame_id", "color_intrinsics", "depth_to_color"}
    assert set(fresh) - set(golden) == added, "the paper layout's frames.json changed"
    assert {k: fresh[k] for k in golden} == golden, "the paper layout's frames.json changed"
    assert (fresh["color_intrinsics"], fresh["depth_to_color"]) == (None, None)
    assert sorted(p.name for p in (tmp_path / "fresh").iterdir()) == sorted(
        p.name for p in PAPER.iterdir()
    )


def test_threads_stay_out_of_files_and_readers_choose(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=2)
    path = tmp_path / "t.pcdc"
    color = pcdcodec.get_codec("h264", threads=3)
    depth = pcdcodec.get_codec("jpegxl", threads=4)
    with pcdcodec.open(
        path, "w", intrinsics=seq.intrinsics, depth_scale=5000.0, color=color, depth=depth
    ) as w:
        w.write_frames(seq)
    with pcdcodec.open(path) as rec:
        assert "threads" not in rec.codecs["color"]
        assert "threads" not in rec.codecs["depth"]
        assert rec.depth_codec.get_config()["threads"] == 1  # the codec's default
        depths = [f.depth for f in rec]
    with pcdcodec.open(path, threads=2) as rec:
        assert rec.threads == 2
        assert rec.depth_codec.get_config()["threads"] == 2
        assert rec.color_codec is not None
        assert rec.color_codec.get_config()["threads"] == 2
        np.testing.assert_array_equal(rec[1].depth, depths[1])
    with pytest.raises(pcdcodec.InputError, match="threads"):
        pcdcodec.open(path, threads=-1)
    with pytest.raises(pcdcodec.InputError, match="only the option threads"):
        pcdcodec.open(path, "r", overwrite=True)  # type: ignore[call-overload]
    # Files of earlier versions recorded threads: the reader's choice still wins.
    old = codec_for_reading({"id": "jpegxl", "effort": 2, "threads": 8}, kind="depth", threads=3)
    assert old.get_config() == {"id": "jpegxl", "effort": 2, "threads": 3}


@pytest.mark.skipif(
    not Path(sys.executable).with_name("mypy").exists(), reason="mypy is not installed"
)
def test_mypy_checks_open_options(tmp_path: Path) -> None:
    user = tmp_path / "user.py"
    user.write_text(
        "import pcdcodec\n"
        "rec = pcdcodec.open('a.pcdc', threads=2)\n"
        "n: int = len(rec)\n"
        "w = pcdcodec.open('b.pcdc', 'w', intrinsics=None, depth_scale=1000.0)\n"
        "w.write_frames([])\n"
        "bad = pcdcodec.open('c.pcdc', 'w', intrinsic=None)\n"
    )
    mypy = Path(sys.executable).with_name("mypy")
    out = subprocess.run(
        [
            str(mypy),
            "--strict",
            "--follow-imports=silent",
            "--cache-dir",
            str(tmp_path / "c"),
            str(user),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    lines = [line for line in out.stdout.splitlines() if ": error:" in line]
    assert lines, out.stdout
    assert all("user.py:6:" in line for line in lines), out.stdout  # only the misspelt option
    assert 'did you mean "intrinsics"' in out.stdout
