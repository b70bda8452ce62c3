"""pcdcodec.torch: items as the recordings hold them, and DataLoader workers, forked and spawned."""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import CameraIntrinsics, CameraSpec, InputError, InputTypeError
from pcdcodec.errors import PcdcodecWarning

torch = pytest.importorskip("torch")
pt = pytest.importorskip("pcdcodec.torch")
DataLoader = torch.utils.data.DataLoader

FRAMES = 15  # the bundled sample


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two one-camera recordings of the sample in a folder (the second reversed, recorded with
    the training color codec, without poses)."""
    root = tmp_path_factory.mktemp("recs")
    seq = pcdcodec.load_sample()
    frames = list(seq)
    with pcdcodec.open(
        root / "a.pcdc", "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale
    ) as w:
        for f in frames:
            w.write(f.color, f.depth, f.timestamp_ns, pose=f.pose)
    color = pt.TRAINING_COLOR
    with pcdcodec.open(
        root / "b.pcdc", "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, color=color
    ) as w:
        for k, f in enumerate(reversed(frames)):
            w.write(f.color, f.depth, k * 33_000_000)
    return root


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A two-camera rig: "head" every frame of the sample, "wrist" (a crop) every other one."""
    path = tmp_path_factory.mktemp("rig") / "rig.pcdc"
    seq = pcdcodec.load_sample()
    cam = seq.intrinsics
    crop = CameraIntrinsics(320, 240, cam.fx, cam.fy, cam.cx - 160, cam.cy - 120)
    pose = np.eye(4)
    pose[:3, 3] = [0.2, 0.0, 0.0]
    cameras = [
        CameraSpec("head", cam, seq.depth_scale, fps=30.0),
        CameraSpec("wrist", crop, seq.depth_scale, fps=15.0, rig_pose=pose),
    ]
    with pcdcodec.open(path, "w", cameras=cameras) as w:
        for k, f in enumerate(seq):
            w.write("head", f.color, f.depth, f.timestamp_ns)
            if k % 2 == 0:
                w.write(
                    "wrist",
                    np.ascontiguousarray(f.color[120:360, 160:480]),
                    np.ascontiguousarray(f.depth[120:360, 160:480]),
                    f.timestamp_ns + 2_000_000,
                )
    return path


ALL = tuple(pt.FIELDS)


def test_every_field_is_what_the_recording_holds(recordings: Path) -> None:
    ds = pt.RecordingDataset(recordings / "a.pcdc", ALL)
    assert len(ds) == FRAMES
    with pcdcodec.open(recordings / "a.pcdc") as rec:
        for i in (7, 0, 14, 3):
            item, frame = ds[i], rec[i]
            assert list(item) == list(ALL)
            assert np.array_equal(item["color"], frame.color)
            assert item["depth"].dtype == np.uint16
            assert np.array_equal(item["depth"], frame.depth)
            metres = item["depth_metres"]
            assert metres.dtype == np.float32
            assert np.array_equal(metres, (frame.depth / np.float32(rec.depth_scale)))
            points, colors = frame.to_points()
            assert np.array_equal(item["points"], points)
            assert np.array_equal(item["point_colors"], colors)
            assert np.array_equal(
                item["organized"], rec.projector.to_organized(frame.depth), equal_nan=True
            )
            assert np.array_equal(item["intrinsics"], rec.intrinsics.K)
            assert frame.pose is not None
            assert np.array_equal(item["pose"], frame.pose)
            assert np.array_equal(item["rig_pose"], np.eye(4))
            assert item["timestamp"] == frame.timestamp_ns
            assert item["camera"] == rec.frame_id
            assert item["source"] == str(recordings / "a.pcdc")
            assert item["index"] == i


def test_training_color_makes_every_frame_a_keyframe(recordings: Path) -> None:
    """With TRAINING_COLOR a random frame decodes its own color packet only, and holds no frame
    back (every frame handed in is in the file as it goes)."""
    assert pt.TRAINING_COLOR["gop"] == 1
    assert pt.TRAINING_COLOR["low_delay"] is True
    sample = list(pcdcodec.load_sample())
    with pcdcodec.open(recordings / "b.pcdc") as rec:
        assert rec.color_codec is not None
        assert rec.color_codec.name == pt.TRAINING_COLOR["id"]
        assert len(rec.packet_timestamps) == len(rec) == FRAMES
        assert rec.keyframes == list(range(FRAMES))
        # Lossy, but close: every frame's color is within a few grey levels of the original.
        for i, original in ((0, sample[-1]), (FRAMES - 1, sample[0])):
            error = np.abs(rec[i].color.astype(np.int16) - original.color.astype(np.int16))
            assert error.mean() < 4.0


def test_depth_alone_skips_color_and_still_has_the_pose(
    recordings: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pcdcodec.open(recordings / "a.pcdc") as rec:
        frames = [rec[i] for i in range(FRAMES)]

    def no_color(*args: Any) -> None:
        raise AssertionError("color was decoded")

    monkeypatch.setattr(pcdcodec.Recording, "_color", no_color)
    ds = pt.RecordingDataset(recordings / "a.pcdc", ["depth", "pose", "index"])
    for i in (5, 2, 9):
        item = ds[i]
        assert list(item) == ["depth", "pose", "index"]
        assert np.array_equal(item["depth"], frames[i].depth)
        assert np.array_equal(item["pose"], frames[i].pose)
    with pytest.raises(pcdcodec.DecodeError, match="color was decoded"):  # the patch works
        pt.RecordingDataset(recordings / "a.pcdc", ["color"])[0]


def test_a_frame_without_a_pose_gives_nan(recordings: Path) -> None:
    ds = pt.RecordingDataset(recordings / "b.pcdc", ["pose"])
    assert np.isnan(ds[0]["pose"]).all()


def test_many_recordings_a_folder_a_glob_and_a_list(recordings: Path) -> None:
    a, b = str(recordings / "a.pcdc"), str(recordings / "b.pcdc")
    by_folder = pt.RecordingDataset(recordings, ["source", "index", "depth"])
    by_glob = pt.RecordingDataset(str(recordings / "*.pcdc"), ["source", "index"])
    by_list = pt.RecordingDataset([b, a, b], ["source", "index"])
    assert by_folder.sources == [a, b] == by_glob.sources
    assert by_list.sources == [b, a]  # each file once, in the order given
    assert len(by_folder) == 2 * FRAMES
    assert by_folder[FRAMES + 2]["source"] == b
    assert by_folder[FRAMES + 2]["index"] == 2
    assert by_folder[-1]["index"] == FRAMES - 1
    assert np.array_equal(by_folder[FRAMES]["depth"], by_folder[FRAMES - 1]["depth"])  # reversed
    assert by_list[0]["source"] == b


def test_bad_arguments_are_refused(recordings: Path, tmp_path: Path) -> None:
    path = recordings / "a.pcdc"
    with pytest.raises(InputError, match="unknown field 'rgb'"):
        pt.RecordingDataset(path, ["rgb"])
    with pytest.raises(InputError, match="twice"):
        pt.RecordingDataset(path, ["depth", "depth"])
    with pytest.raises(InputError, match="does not exist"):
        pt.RecordingDataset(tmp_path / "none.pcdc")
    with pytest.raises(InputError, match=r"holds no \.pcdc"):
        pt.RecordingDataset(tmp_path)
    with pytest.raises(InputError, match="matches no recording"):
        pt.RecordingDataset(str(tmp_path / "*.pcdc"))
    with pytest.raises(InputTypeError):
        pt.RecordingDataset(3)
    with pytest.raises(
        InputError, match=r"no recording has camera 'wrist'; their cameras are \['camera'\]"
    ):
        pt.RecordingDataset(path, cameras=["wrist"])
    with pytest.raises(InputTypeError, match="transform"):
        pt.RecordingDataset(path, transform=3)
    with pytest.raises(InputError, match="threads"):
        pt.RecordingDataset(path, threads=-1)
    ds = pt.RecordingDataset(path)
    with pytest.raises(IndexError):
        ds[FRAMES]
    with pytest.raises(InputTypeError):
        ds[1.0]  # type: ignore[index]


def test_depth_only_recordings_refuse_color_fields(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample()
    path = tmp_path / "d.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, color=None
    ) as w:
        w.write(None, seq[0].depth, 0)
    with pytest.raises(InputError, match="without color"):
        pt.RecordingDataset(path)
    assert np.array_equal(pt.RecordingDataset(path, "depth")[0]["depth"], seq[0].depth)


def _scale(item: dict[str, Any]) -> dict[str, Any]:
    return {"half": item["depth_metres"] / 2, "index": item["index"]}


def test_tensors_and_transform(recordings: Path) -> None:
    ds = pt.RecordingDataset(
        recordings / "a.pcdc", ["color", "depth", "depth_metres", "index"], tensors=True
    )
    item = ds[4]
    assert isinstance(item["color"], torch.Tensor)
    assert item["color"].dtype == torch.uint8
    assert item["depth"].dtype == torch.uint16
    assert isinstance(item["index"], int)
    plain = pt.RecordingDataset(recordings / "a.pcdc", ["depth_metres", "index"])
    assert np.array_equal(item["depth_metres"].numpy(), plain[4]["depth_metres"])
    moved = pt.RecordingDataset(recordings / "a.pcdc", ["depth_metres", "index"], transform=_scale)
    assert list(moved[4]) == ["half", "index"]
    assert np.array_equal(moved[4]["half"], plain[4]["depth_metres"] / 2)


def test_the_dataset_pickles_small_before_and_after_reading(recordings: Path) -> None:
    ds = pt.RecordingDataset(recordings, ALL)
    before = pickle.dumps(ds)
    ds[3]
    ds[FRAMES + 3]
    assert ds._readers._open  # readers are open in this process now
    after = pickle.dumps(ds)
    assert len(before) < 2048
    assert len(after) == len(before)  # no file, no decoder, no decoded frame in it
    copy = pickle.loads(after)
    assert not copy._readers._open
    assert np.array_equal(copy[FRAMES + 3]["depth"], ds[FRAMES + 3]["depth"])
    ds.close()


def _loader_items(ds: Any, context: str, **options: Any) -> list[dict[str, Any]]:
    loader = DataLoader(ds, num_workers=2, multiprocessing_context=context, **options)
    out = []
    for batch in loader:
        if options.get("batch_size", 1) is None:  # items one by one, not batched
            out.append(batch)
            continue
        for k in range(len(batch["index"])):
            out.append({name: value[k] for name, value in batch.items()})
    return out


@pytest.mark.parametrize("context", ["fork", "spawn"])
def test_a_dataloader_with_two_workers(recordings: Path, context: str) -> None:
    ds = pt.RecordingDataset(recordings, ["depth", "color", "source", "index"])
    ds[0]  # this process has its readers open: forked workers must open their own
    got = _loader_items(ds, context, batch_size=4, shuffle=True)
    assert len(got) == 2 * FRAMES
    keys = sorted((item["source"], int(item["index"])) for item in got)
    assert keys == sorted((s, i) for s in ds.sources for i in range(FRAMES))
    for item in got[:: len(got) // 6]:
        j = ds.sources.index(item["source"]) * FRAMES + int(item["index"])
        want = ds[j]
        assert np.array_equal(item["depth"].numpy(), want["depth"])
        assert np.array_equal(item["color"].numpy(), want["color"])
    assert ds[0]["index"] == 0  # this process's readers still read


def test_the_iterable_dataset_splits_the_frames_between_workers(recordings: Path) -> None:
    ds = pt.IterableRecordingDataset(recordings, ["depth", "source", "index"])
    assert len(ds) == 2 * FRAMES
    got = _loader_items(ds, "fork", batch_size=None)
    keys = [(item["source"], int(item["index"])) for item in got]
    every = [(s, i) for s in ds.dataset.sources for i in range(FRAMES)]
    assert sorted(keys) == sorted(every)  # each frame once
    # each worker reads its share in order: worker 0 the first half, worker 1 the second
    first = [k for k in keys if every.index(k) < FRAMES]
    assert first == every[:FRAMES]
    for item in got[::7]:
        j = every.index((item["source"], int(item["index"])))
        assert np.array_equal(item["depth"], ds.dataset[j]["depth"])


def test_in_order_reading_gives_the_random_frames(recordings: Path) -> None:
    ds = pt.IterableRecordingDataset(recordings / "b.pcdc", ["color", "depth"])
    random = pt.RecordingDataset(recordings / "b.pcdc", ["color", "depth"])
    with pcdcodec.open(recordings / "b.pcdc") as rec:
        frames = list(rec)
    for k, item in enumerate(ds):
        assert np.array_equal(item["color"], frames[k].color)
        assert np.array_equal(item["depth"], frames[k].depth)
    for k in (11, 2, 3, 14, 0):
        assert np.array_equal(random[k]["color"], frames[k].color)


def test_a_rig_gives_one_item_per_camera_frame(rig: Path) -> None:
    ds = pt.RecordingDataset(rig, ["camera", "index", "depth", "rig_pose", "intrinsics"])
    assert len(ds) == FRAMES + 8
    assert [ds[i]["camera"] for i in (0, FRAMES - 1, FRAMES, FRAMES + 7)] == [
        "head",
        "head",
        "wrist",
        "wrist",
    ]
    with pcdcodec.open(rig) as rec:
        wrist = ds[FRAMES + 3]
        assert np.array_equal(wrist["depth"], rec.frames("wrist")[3].depth)
        assert wrist["depth"].shape == (240, 320)
        assert np.array_equal(wrist["rig_pose"], rec.rig_poses["wrist"])
        assert np.array_equal(wrist["intrinsics"], rec.cameras["wrist"].intrinsics.K)
    only = pt.RecordingDataset(rig, ["camera", "index"], cameras=["wrist"])
    assert len(only) == 8
    assert {only[i]["camera"] for i in range(8)} == {"wrist"}


def test_a_rig_gives_one_item_per_frame_set(rig: Path, recordings: Path) -> None:
    ds = pt.RecordingDataset(rig, ["index", "timestamp", "depth"], framesets=True)
    with pcdcodec.open(rig) as rec:
        sets = rec.framesets()
        complete = [s for s in range(len(sets)) if not (sets.matches[s] < 0).any()]
        assert len(ds) == len(complete) == 8
        for k in (0, 5):
            item = ds[k]
            assert list(item) == ["head", "wrist"]
            row = sets.matches[complete[k]]
            assert item["head"]["index"] == row[0]
            assert item["wrist"]["index"] == row[1]
            assert np.array_equal(item["wrist"]["depth"], rec.frames("wrist")[int(row[1])].depth)
    loader = DataLoader(ds, batch_size=2, num_workers=2, multiprocessing_context="fork")
    batches = list(loader)
    assert batches[0]["wrist"]["depth"].shape == (2, 240, 320)
    assert sorted(int(i) for b in batches for i in b["wrist"]["index"]) == list(range(8))
    swapped = pt.RecordingDataset(rig, ["index"], framesets=True, cameras=["wrist", "head"])
    assert list(swapped[0]) == ["wrist", "head"]
    with pytest.raises(InputError, match="no camera 'wrist'"):
        pt.RecordingDataset([rig, recordings / "a.pcdc"], framesets=True, cameras=["wrist"])


def test_cameras_and_fields_arguments_are_checked(rig: Path) -> None:
    by_generator = pt.RecordingDataset(rig, ["camera"], cameras=(c for c in ["wrist"]))
    assert len(by_generator) == 8
    with pytest.raises(InputError, match="twice"):
        pt.RecordingDataset(rig, ["index"], cameras=["head", "head"])
    with pytest.raises(InputError, match="twice"):
        pt.RecordingDataset(rig, ["index"], cameras=["head", "head"], framesets=True)
    with pytest.raises(InputTypeError, match="cameras must be a list of camera names, got 3"):
        pt.RecordingDataset(rig, cameras=3)  # type: ignore[arg-type]
    with pytest.raises(InputTypeError, match=r"each field must be a field name, got \['depth'\]"):
        pt.RecordingDataset(rig, [["depth"]])


def _write(path: Path, frames: int, cameras: tuple[str, ...] = ()) -> None:
    """``frames`` frames of the sample, of one camera or of each of ``cameras``."""
    seq = pcdcodec.load_sample()
    if cameras:
        specs = [CameraSpec(c, seq.intrinsics, seq.depth_scale, fps=30.0) for c in cameras]
        options: dict[str, Any] = {"cameras": specs}
    else:
        options = {"intrinsics": seq.intrinsics, "depth_scale": seq.depth_scale}
    with pcdcodec.open(path, "w", overwrite=True, **options) as w:
        for f in list(seq)[:frames]:
            for c in cameras:
                w.write(c, f.color, f.depth, f.timestamp_ns)
            if not cameras:
                w.write(f.color, f.depth, f.timestamp_ns)


def test_a_recording_rewritten_shorter_is_an_error_not_the_end(tmp_path: Path) -> None:
    path = tmp_path / "a.pcdc"
    _write(path, 6)
    ds = pt.RecordingDataset(path, ["depth"])
    _write(path, 2)
    with pytest.raises(InputError, match=r"has 2 frames of camera .* 6 when the dataset was made"):
        list(ds)  # an IndexError would end the iteration after two items, silently
    rig = tmp_path / "rig.pcdc"
    _write(rig, 6, ("head", "wrist"))
    sets = pt.RecordingDataset(rig, ["index"], framesets=True)
    assert len(sets) == 6
    _write(rig, 2, ("head", "wrist"))
    with pytest.raises(InputError, match="has 2 frame sets, 6 when the dataset was made"):
        sets[0]


def test_a_dataset_without_any_item_is_refused(tmp_path: Path) -> None:
    rig = tmp_path / "rig.pcdc"
    _write(rig, 3, ("head", "wrist"))
    lonely = tmp_path / "lonely.pcdc"
    seq = pcdcodec.load_sample()
    specs = [CameraSpec(c, seq.intrinsics, seq.depth_scale, fps=30.0) for c in ("head", "wrist")]
    with pcdcodec.open(lonely, "w", cameras=specs) as w:
        for f in list(seq)[:3]:
            w.write("head", f.color, f.depth, f.timestamp_ns)  # wrist records nothing
    with pytest.raises(InputError, match=r"no complete frame set .*\['head', 'wrist'\]"):
        pt.RecordingDataset(lonely, ["depth"], framesets=True)
    assert len(pt.RecordingDataset([lonely, rig], ["depth"], framesets=True)) == 3
    assert len(pt.RecordingDataset(lonely, ["depth"])) == 3  # head's frames, one by one
    empty = tmp_path / "empty.pcdc"
    with pcdcodec.open(empty, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale):
        pass
    with pytest.raises(InputError, match="hold no frame"):
        pt.RecordingDataset(empty)
    assert len(pt.RecordingDataset([empty, rig], ["depth"])) == 6


# -- frames kept by recover without their color ---------------------------------------------


@pytest.fixture(scope="module")
def recovered(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recording whose color from frame 3 on was lost to a flipped byte, recovered: frames
    3, 4 and 5 read with ``color`` None."""
    from .test_recover_damage import recovered_without_color

    back = recovered_without_color(tmp_path_factory.mktemp("recovered"))
    with pcdcodec.open(back) as rec:
        assert rec.color_missing == [3, 4, 5]
    return back


def test_a_recording_with_frames_without_color_is_refused_for_color(recovered: Path) -> None:
    for fields in (["color"], ["depth", "point_colors"]):
        with pytest.raises(InputError) as err:
            pt.RecordingDataset(recovered, fields)
        message = str(err.value)
        assert repr(str(recovered)) in message
        assert "3 frame(s)" in message
        assert "frames 3, 4, 5" in message
        assert "skip_missing_color=True" in message
    with pytest.raises(InputError, match="skip_missing_color=True"):
        pt.IterableRecordingDataset(recovered)
    with pytest.raises(InputTypeError, match="skip_missing_color must be True or False"):
        pt.RecordingDataset(recovered, skip_missing_color="yes")


def test_fields_without_color_read_every_frame_of_it(recovered: Path) -> None:
    with pcdcodec.open(recovered) as rec:
        want = [rec.depth(i) for i in range(len(rec))]
    dataset = pt.RecordingDataset(recovered, ["depth", "index"])
    assert len(dataset) == 6
    assert dataset.skipped == {}
    for i, item in enumerate(dataset):
        assert item["index"] == i
        np.testing.assert_array_equal(item["depth"], want[i])


@pytest.mark.parametrize("framesets", [False, True])
def test_skip_missing_color_leaves_those_frames_out_and_says_so(
    recovered: Path, framesets: bool
) -> None:
    with pcdcodec.open(recovered) as rec:
        frames = list(rec)
    with pytest.warns(PcdcodecWarning, match=r"3 item\(s\) left out"):
        dataset = pt.RecordingDataset(
            recovered,
            ["color", "depth", "index"],
            skip_missing_color=True,
            framesets=framesets,
        )
    assert len(dataset) == 3
    assert dataset.skipped == {str(recovered): 3}
    assert "3 left out without color" in repr(dataset)
    items = [dataset[i] for i in range(len(dataset))]
    if framesets:
        items = [next(iter(item.values())) for item in items]
    assert [item["index"] for item in items] == [0, 1, 2]
    for item in items:
        frame = frames[item["index"]]
        assert frame.color is not None
        np.testing.assert_array_equal(item["color"], frame.color)
        np.testing.assert_array_equal(item["depth"], frame.depth)
    # The default collate gets no None; a dataset pickled into a worker skips the same frames.
    again = pickle.loads(pickle.dumps(dataset))
    batch = next(iter(DataLoader(again, batch_size=3)))
    colors = next(iter(batch.values()))["color"] if framesets else batch["color"]
    assert tuple(colors.shape) == (3, *frames[0].color.shape)


def test_iterable_dataset_skips_the_same_frames(recovered: Path) -> None:
    with pytest.warns(PcdcodecWarning):
        dataset = pt.IterableRecordingDataset(recovered, skip_missing_color=True)
    assert [item["color"] is not None for item in dataset] == [True] * 3
    assert len(dataset) == 3
