"""Pairing color and depth streams: associate() against a brute-force greedy, TUM's own
association lists, and the streaming Synchronizer against associate()."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pcdcodec.datasets import sample_dir
from pcdcodec.errors import InputError, InputTypeError
from pcdcodec.sync import Association, Synchronizer, _greedy_match, associate

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
MS = 1_000_000
PERIOD = 33_333_333  # 30 Hz, ns


def brute_force(
    colors: list[int], depths: list[int], max_difference: int, offset: int = 0
) -> list[tuple[int, int]]:
    """The greedy rule spelled out over every candidate pair: O(n·m), for checking only."""
    candidates = sorted(
        (abs(c - (d + offset)), i, j)
        for i, c in enumerate(colors)
        for j, d in enumerate(depths)
        if abs(c - (d + offset)) <= max_difference
    )
    used_c: set[int] = set()
    used_d: set[int] = set()
    pairs = []
    for _, i, j in candidates:
        if i not in used_c and j not in used_d:
            used_c.add(i)
            used_d.add(j)
            pairs.append((i, j))
    return sorted(pairs)


def stream(
    n: int, rng: np.random.Generator, *, jitter: int, drop: float, shift: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """A 30 Hz stream of ``n`` frames with uniform jitter (ns) and a fraction dropped; returns
    the kept stamps and their frame numbers."""
    frames = np.arange(n)
    stamps = frames * PERIOD + shift + rng.integers(-jitter, jitter + 1, n)
    keep = rng.random(n) >= drop
    return stamps[keep], frames[keep]


def seconds_to_ns(text: str) -> int:
    whole, _, frac = text.partition(".")
    return int(whole) * 1_000_000_000 + int((frac + "000000000")[:9])


def read_tum(root: Path) -> tuple[list[int], list[int], list[tuple[int, int]]]:
    """rgb.txt and depth.txt stamps, and associations.txt as (rgb, depth) stamp pairs, in ns."""

    def rows(name: str) -> list[list[str]]:
        lines = (root / name).read_text().splitlines()
        return [line.split() for line in lines if line.strip() and not line.startswith("#")]

    rgb = [seconds_to_ns(r[0]) for r in rows("rgb.txt")]
    depth = [seconds_to_ns(r[0]) for r in rows("depth.txt")]
    pairs = [(seconds_to_ns(r[0]), seconds_to_ns(r[2])) for r in rows("associations.txt")]
    return rgb, depth, pairs


def check_tum(root: Path) -> Association:
    rgb, depth, expected = read_tum(root)
    result = associate(rgb, depth, max_difference=20 * MS)
    assert [(rgb[i], depth[j]) for i, j in result] == expected
    return result


# -- associate(): hand-made cases ----------------------------------------------------------


def test_exact_matches() -> None:
    stamps = [0, PERIOD, 2 * PERIOD, 3 * PERIOD]
    result = associate(stamps, stamps)
    assert list(result) == [(0, 0), (1, 1), (2, 2), (3, 3)]
    assert result.differences.tolist() == [0, 0, 0, 0]
    assert result.unmatched_color.size == 0
    assert result.unmatched_depth.size == 0


def test_ties_go_to_the_earlier_stamp() -> None:
    # One color exactly between two depths, and one depth exactly between two colors.
    assert list(associate([10], [0, 20], max_difference=10)) == [(0, 0)]
    assert list(associate([0, 20], [10], max_difference=10)) == [(0, 0)]
    # Equal differences across pairs: the earlier color is served first and wins depth 0.
    result = associate([0, 10], [5], max_difference=5)
    assert list(result) == [(0, 0)]
    assert result.unmatched_color.tolist() == [1]


def test_greedy_takes_the_closest_pair_first() -> None:
    # Color 0's nearest depth is 9, but color 10 is closer to it; color 0 is left unmatched,
    # as associate.py would leave it, rather than stealing depth 9.
    result = associate([0, 10], [9], max_difference=20)
    assert list(result) == [(1, 0)]
    assert result.unmatched_color.tolist() == [0]


def test_nested_pairs_with_a_wide_tolerance() -> None:
    # depth 0 | color 10, depth 11 | color 21: (10, 11) first, then (21, 0) around it, so the
    # depth indices are not increasing, as with associate.py.
    result = associate([10, 21], [0, 11], max_difference=25)
    assert list(result) == [(0, 1), (1, 0)]
    assert result.differences.tolist() == [-1, 21]


def test_a_frame_dropped_in_each_stream() -> None:
    color_frames = np.delete(np.arange(10), 3)
    depth_frames = np.delete(np.arange(10), 6)
    colors = color_frames * PERIOD + 1 * MS
    depths = depth_frames * PERIOD - 2 * MS
    result = associate(colors, depths)
    paired_frames = [(int(color_frames[i]), int(depth_frames[j])) for i, j in result]
    assert paired_frames == [(f, f) for f in range(10) if f not in (3, 6)]
    assert colors[result.unmatched_color].tolist() == [6 * PERIOD + 1 * MS]
    assert depths[result.unmatched_depth].tolist() == [3 * PERIOD - 2 * MS]
    assert set(result.differences.tolist()) == {3 * MS}


def test_offset_models_a_lagging_depth_clock() -> None:
    frames = np.arange(20)
    colors = frames * PERIOD
    depths = colors - 30 * MS  # the depth clock runs 30 ms behind
    plain = associate(colors, depths)
    # Without the offset each color pairs with the *next* frame's depth, 3.3 ms away.
    assert list(plain)[:3] == [(0, 1), (1, 2), (2, 3)]
    shifted = associate(colors, depths, offset=30 * MS)
    assert list(shifted) == [(i, i) for i in range(20)]
    assert shifted.differences.tolist() == [0] * 20


def test_tolerance_boundary_is_inclusive() -> None:
    assert list(associate([0], [20 * MS])) == [(0, 0)]
    assert list(associate([0], [20 * MS + 1])) == []
    assert list(associate([0], [-20 * MS], max_difference=20 * MS)) == [(0, 0)]
    assert list(associate([5, 7], [5, 8], max_difference=0)) == [(0, 0)]
    # With an offset the boundary is measured after shifting the depth stamps.
    assert list(associate([0], [25 * MS], offset=-5 * MS)) == [(0, 0)]
    assert list(associate([0], [25 * MS], offset=-5 * MS + 1)) == []


@pytest.mark.parametrize(
    ("colors", "depths"),
    [
        ([], []),
        ([], [1, 2, 3]),
        ([1, 2], []),
        (np.array([], dtype=np.int64), np.array([5], dtype=np.uint32)),
    ],
)
def test_empty_inputs_give_no_pairs(colors: Any, depths: Any) -> None:
    result = associate(colors, depths)
    assert len(result) == 0
    assert result.pairs.shape == (0, 2)
    assert result.pairs.dtype == np.int64
    assert result.unmatched_color.tolist() == list(range(len(colors)))
    assert result.unmatched_depth.tolist() == list(range(len(depths)))
    assert "paired 0 of" in result.summary()


def test_association_fields_and_summary() -> None:
    colors = [0, 100 * MS, 200 * MS]
    depths = [int(3.1 * MS) + 100 * MS, 202 * MS]
    result = associate(colors, depths)
    assert isinstance(result, Association)
    assert result.pairs.dtype == np.int64
    assert result.differences.dtype == np.int64
    assert result.pairs.tolist() == [[1, 0], [2, 1]]
    assert result.differences.tolist() == [-int(3.1 * MS), -2 * MS]
    assert len(result) == 2
    assert list(result) == [(1, 0), (2, 1)]
    assert all(type(i) is int for pair in result for i in pair)
    assert result.summary() == (
        "paired 2 of 3 color and 2 depth frames; max |Δt| 3.1 ms; "
        "1 color and 0 depth frames unmatched"
    )
    with pytest.raises(ValueError, match="read-only"):
        result.pairs[0, 0] = 5
    with pytest.raises(AttributeError):
        result.pairs = result.pairs  # type: ignore[misc]


def test_integer_dtypes_and_plain_lists_agree() -> None:
    colors = [0, 30, 70, 100]
    depths = [2, 33, 95]
    expected = list(associate(colors, depths, max_difference=5))
    assert expected == [(0, 0), (1, 1), (3, 2)]
    for dtype in (np.int32, np.uint16, np.uint64, np.int64):
        got = associate(
            np.array(colors, dtype=dtype), np.array(depths, dtype=dtype), max_difference=5
        )
        assert list(got) == expected


# -- associate(): errors ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("colors", "match"),
    [
        ([0, 10, 5, 20], r"color_stamps must be strictly increasing, but index 2 \(5 ns\)"),
        ([0, 10, 10], r"index 2 \(10 ns\) is not after index 1 \(10 ns\)"),
        (np.array([[1, 2], [3, 4]]), r"1-D, got shape \(2, 2\)"),
        (np.int64(7), r"1-D, got shape \(\)"),
        (np.array([2**63], dtype=np.uint64), "above the int64 maximum"),
    ],
)
def test_bad_stamps_raise_input_error(colors: Any, match: str) -> None:
    with pytest.raises(InputError, match=match):
        associate(colors, [0])


def test_decreasing_depth_stamps_are_named() -> None:
    with pytest.raises(InputError, match=r"depth_stamps .* index 1 \(-1 ns\)"):
        associate([0], [0, -1])


@pytest.mark.parametrize(
    "stamps",
    [
        [0.0, 0.033],
        np.array([1.5, 2.5]),
        np.array([], dtype=np.float64),
        np.array([True, False]),
        ["0", "1"],
    ],
)
def test_non_integer_stamps_raise_input_type_error(stamps: Any) -> None:
    with pytest.raises(InputTypeError, match="color_stamps must be integer nanoseconds"):
        associate(stamps, [0])
    # Also a TypeError and a ValueError for callers that do not know pcdcodec.
    with pytest.raises(TypeError):
        associate([0], stamps)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"max_difference": 0.02}, InputTypeError, r"max_difference must be an int .*0\.02"),
        ({"max_difference": True}, InputTypeError, "max_difference must be an int"),
        ({"max_difference": "20ms"}, InputTypeError, "max_difference must be an int"),
        ({"max_difference": -1}, InputError, "max_difference must be at least 0 ns, got -1"),
        ({"offset": 1.5}, InputTypeError, r"offset must be an int .*1\.5"),
        ({"offset": 2**63}, InputError, "int64 range"),
    ],
)
def test_bad_settings(kwargs: dict[str, Any], error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        associate([0, 1], [0, 1], **kwargs)


def test_numpy_integer_settings_are_accepted() -> None:
    result = associate([0], [5], max_difference=np.int64(5), offset=np.int32(0))
    assert list(result) == [(0, 0)]


# -- associate(): against the brute force ----------------------------------------------------


def test_matches_brute_force_on_random_inputs() -> None:
    rng = np.random.default_rng(20240611)
    for _ in range(400):
        n, m = rng.integers(0, 25, 2)
        span = int(rng.integers(1, 150))
        colors = np.unique(rng.integers(0, span, n))
        depths = np.unique(rng.integers(0, span, m))
        tolerance = int(rng.integers(0, 50))
        offset = int(rng.integers(-10, 11))
        expected = brute_force(colors.tolist(), depths.tolist(), tolerance, offset)
        result = associate(colors, depths, max_difference=tolerance, offset=offset)
        assert list(result) == expected
        pairs = result.pairs
        assert (
            result.differences.tolist()
            == (colors[pairs[:, 0]] - depths[pairs[:, 1]] - offset).tolist()
        )
        # The heap path alone gives the same pairs as the vectorised rounds.
        ci, di = _greedy_match(colors, depths + offset, tolerance, vector_rounds=False)
        assert sorted(zip(ci.tolist(), di.tolist(), strict=True)) == expected


def test_chain_of_growing_gaps_hands_over_to_the_heap() -> None:
    # Alternating color/depth stamps whose gaps grow by 1 ns: each vectorised round can only
    # accept the first pair, so the heap must finish, and the greedy pairs stay neighbours.
    positions = np.concatenate([[0], np.cumsum(np.arange(1, 4001))])
    colors, depths = positions[0::2], positions[1::2]
    result = associate(colors, depths, max_difference=10**9)
    assert list(result) == [(i, i) for i in range(depths.size)]
    assert result.unmatched_color.tolist() == [colors.size - 1]


def test_100k_jittered_stamps() -> None:
    rng = np.random.default_rng(7)
    colors, color_frames = stream(100_000, rng, jitter=3 * MS, drop=0.02)
    depths, depth_frames = stream(100_000, rng, jitter=3 * MS, drop=0.02, shift=1 * MS)
    result = associate(colors, depths)
    # Frames are 33 ms apart and jitter is ±3 ms: exactly the frames kept in both pair up.
    assert np.array_equal(color_frames[result.pairs[:, 0]], depth_frames[result.pairs[:, 1]])
    assert len(result) == np.intersect1d(color_frames, depth_frames).size
    assert np.abs(result.differences).max() <= 7 * MS
    assert len(np.unique(result.pairs[:, 1])) == len(result)


def test_greedy_leaves_no_unmatched_pair_within_tolerance() -> None:
    rng = np.random.default_rng(3)
    colors, _ = stream(20_000, rng, jitter=14 * MS, drop=0.1)
    depths, _ = stream(20_000, rng, jitter=14 * MS, drop=0.1)
    colors, depths = np.unique(colors), np.unique(depths)
    result = associate(colors, depths)
    assert np.abs(result.differences).max() <= 20 * MS
    left_c = colors[result.unmatched_color]
    left_d = depths[result.unmatched_depth]
    if left_c.size and left_d.size:
        k = np.clip(np.searchsorted(left_d, left_c), 1, left_d.size - 1)
        nearest = np.minimum(np.abs(left_c - left_d[k - 1]), np.abs(left_c - left_d[k]))
        assert nearest.min() > 20 * MS
    assert len(result) + left_c.size == colors.size


# -- associate(): the TUM lists ------------------------------------------------------------


def test_bundled_sample_reproduces_its_associations() -> None:
    result = check_tum(sample_dir())
    assert len(result) == 15


@pytest.mark.shared_data
def test_tum_fr1_rpy_reproduces_associate_py() -> None:
    root = SHARED_DATA / "tum_fr1_rpy"
    if not (root / "associations.txt").is_file():
        pytest.skip(f"{root} is not present")
    result = check_tum(root)
    assert len(result) >= 90
    assert np.abs(result.differences).max() < 20 * MS


# -- Synchronizer ------------------------------------------------------------------------------


def feed(
    sync: Synchronizer[Any, Any],
    colors: np.ndarray,
    depths: np.ndarray,
    color_arrival: np.ndarray,
    depth_arrival: np.ndarray,
) -> list[tuple[int, Any, int, Any]]:
    """Feed both streams in order of arrival time; items are the stream indices."""
    events = sorted(
        [(int(t), 0, i) for i, t in enumerate(color_arrival)]
        + [(int(t), 1, j) for j, t in enumerate(depth_arrival)]
    )
    out = []
    for _, kind, i in events:
        if kind == 0:
            out += sync.add_color(int(colors[i]), i)
        else:
            out += sync.add_depth(int(depths[i]), i)
    return out + sync.flush()


def test_pair_is_ready_once_the_other_stream_moves_on() -> None:
    sync: Synchronizer[str, str] = Synchronizer()
    assert sync.add_color(0, "c0") == []
    # A color at 0.5 ms could still arrive and be closer to this depth.
    assert sync.add_depth(1 * MS, "d0") == []
    assert sync.pending == (1, 1)
    assert sync.add_color(PERIOD, "c1") == [(0, "c0", 1 * MS, "d0")]
    assert sync.pending == (1, 0)
    assert sync.paired_count == 1
    assert sync.flush() == []
    assert sync.dropped_color == [PERIOD]
    assert sync.dropped_depth == []


def test_exact_match_is_ready_at_once() -> None:
    sync: Synchronizer[int, int] = Synchronizer()
    assert sync.add_depth(5 * MS, 1) == []
    assert sync.add_color(5 * MS, 2) == [(5 * MS, 2, 5 * MS, 1)]


def test_hopeless_stamp_is_dropped_before_flush() -> None:
    sync: Synchronizer[int, int] = Synchronizer(max_difference=20 * MS)
    sync.add_color(0, 0)
    assert sync.add_depth(20 * MS - 1, 0) == []  # within tolerance: could still pair
    assert sync.dropped_color == []
    sync2: Synchronizer[int, int] = Synchronizer(max_difference=20 * MS)
    sync2.add_color(0, 0)
    assert sync2.add_depth(50 * MS, 0) == []
    assert sync2.dropped_color == [0]
    assert sync2.pending == (0, 1)
    assert sync2.overflow_count == 0


def test_offset_in_the_synchronizer_reports_raw_depth_stamps() -> None:
    sync: Synchronizer[str, str] = Synchronizer(offset=30 * MS)
    out = sync.add_depth(-30 * MS, "d")
    out += sync.add_color(0, "c")
    out += sync.flush()
    assert out == [(0, "c", -30 * MS, "d")]


# Stamps (ns, tolerance 10) where the pair (26, 24) is final before color 13 is decided:
# a color at 27 or 28 would still take depth 21 from color 13.
UNDECIDED = [("d", 21), ("c", 13), ("c", 26), ("d", 24), ("d", 35)]


def feed_events(
    sync: Synchronizer[int, int], events: list[tuple[str, int]]
) -> list[list[tuple[int, int]]]:
    calls = []
    for kind, t in events:
        out = sync.add_color(t, t) if kind == "c" else sync.add_depth(t, t)
        calls.append([(c, d) for c, _, d, _ in out])
    return calls


def test_ordered_output_holds_a_later_pair_back() -> None:
    sync: Synchronizer[int, int] = Synchronizer(max_difference=10)
    calls = feed_events(sync, [*UNDECIDED, ("c", 40)])
    assert calls == [[], [], [], [], [], [(13, 21), (26, 24)]]


def test_unordered_output_is_as_soon_as_final() -> None:
    sync: Synchronizer[int, int] = Synchronizer(max_difference=10, ordered=False)
    calls = feed_events(sync, [*UNDECIDED, ("c", 40)])
    assert calls == [[], [], [], [], [(26, 24)], [(13, 21)]]


def test_a_later_stamp_can_still_change_the_pairing() -> None:
    sync: Synchronizer[int, int] = Synchronizer(max_difference=10)
    calls = feed_events(sync, [*UNDECIDED, ("c", 27)])
    assert calls[-1] == [(26, 24), (27, 21)]
    assert sync.dropped_color == [13]
    assert [(c, d) for c, _, d, _ in sync.flush()] == []
    assert sync.dropped_depth == [35]
    expected = associate([13, 26, 27], [21, 24, 35], max_difference=10)
    assert list(expected) == [(1, 1), (2, 0)]


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("ordered", [True, False])
def test_synchronizer_matches_associate(seed: int, ordered: bool) -> None:
    rng = np.random.default_rng(seed)
    # Jitter close to the tolerance makes pairs wait on each other; depth arrives later.
    jitter = [3, 8, 12, 14][seed] * MS
    colors, _ = stream(1500, rng, jitter=jitter, drop=0.05)
    depths, _ = stream(1500, rng, jitter=jitter, drop=0.05, shift=2 * MS)
    colors, depths = np.unique(colors), np.unique(depths)
    color_arrival = np.maximum.accumulate(colors + rng.integers(5, 15, colors.size) * MS)
    depth_arrival = np.maximum.accumulate(depths + rng.integers(10, 60, depths.size) * MS)
    sync: Synchronizer[int, int] = Synchronizer(ordered=ordered)
    out = feed(sync, colors, depths, color_arrival, depth_arrival)

    expected = associate(colors, depths)
    assert sorted((ci, di) for _, ci, _, di in out) == list(expected)
    assert all(int(colors[ci]) == ct and int(depths[di]) == dt for ct, ci, dt, di in out)
    assert sorted(sync.dropped_color) == colors[expected.unmatched_color].tolist()
    assert sorted(sync.dropped_depth) == depths[expected.unmatched_depth].tolist()
    assert sync.overflow_count == 0
    assert sync.paired_count == len(expected)
    if ordered:
        color_times = [ct for ct, _, _, _ in out]
        assert color_times == sorted(color_times)


def test_synchronizer_matches_brute_force_on_random_interleavings() -> None:
    rng = np.random.default_rng(11)
    for _ in range(300):
        colors = np.unique(rng.integers(0, 120, rng.integers(0, 20)))
        depths = np.unique(rng.integers(0, 120, rng.integers(0, 20)))
        tolerance, offset = int(rng.integers(0, 40)), int(rng.integers(-5, 6))
        # Random arrival: per-stream order kept, the two streams interleaved at random.
        arrival_c = np.cumsum(rng.integers(0, 3, colors.size))
        arrival_d = np.cumsum(rng.integers(0, 3, depths.size))
        sync: Synchronizer[int, int] = Synchronizer(
            max_difference=tolerance, offset=offset, max_queue=1000
        )
        out = feed(sync, colors, depths, arrival_c, arrival_d)
        expected = brute_force(colors.tolist(), depths.tolist(), tolerance, offset)
        assert [(ci, di) for _, ci, _, di in out] == expected


def test_max_queue_drops_the_oldest() -> None:
    sync: Synchronizer[int, int] = Synchronizer(max_queue=5)
    for i in range(20):  # the depth stream stalls
        assert sync.add_color(i * PERIOD, i) == []
        assert sync.pending[0] <= 5
    assert sync.dropped_color == [i * PERIOD for i in range(15)]
    assert sync.overflow_count == 15
    out = []
    for i in range(20):
        out += sync.add_depth(i * PERIOD + 1000, i)
    out += sync.flush()
    assert [(c, d) for _, c, _, d in out] == [(i, i) for i in range(15, 20)]
    assert sync.dropped_depth == [i * PERIOD + 1000 for i in range(15)]
    assert sync.overflow_count == 15  # the depth drops were proven unmatched, not overflow
    assert sync.pending == (0, 0)


def test_flush_pairs_the_rest_and_empties_the_queues() -> None:
    sync: Synchronizer[str, str] = Synchronizer()
    assert sync.add_color(0, "a") == []
    assert sync.add_color(PERIOD, "b") == []
    assert sync.add_depth(2 * MS, "x") == [(0, "a", 2 * MS, "x")]
    # Only the end of the streams settles this one: a color at PERIOD + 6 ms might follow.
    assert sync.add_depth(PERIOD + 5 * MS, "y") == []
    assert sync.pending == (1, 1)
    out = sync.flush()
    assert [(c, d) for _, c, _, d in out] == [("b", "y")]
    assert sync.pending == (0, 0)
    assert sync.flush() == []
    with pytest.raises(InputError, match="not after the previous color timestamp"):
        sync.add_color(PERIOD, "c")


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda s: s.add_color(1.0, None), InputTypeError, "color timestamp must be an int"),
        (lambda s: s.add_depth("5", None), InputTypeError, "depth timestamp must be an int"),
        (
            lambda s: (s.add_depth(10, None), s.add_depth(10, None)),
            InputError,
            "depth timestamp 10 ns is not after the previous depth timestamp 10 ns",
        ),
        (
            lambda s: (s.add_color(10, None), s.add_color(3, None)),
            InputError,
            "color timestamp 3 ns is not after the previous color timestamp 10 ns",
        ),
        (lambda s: s.add_color(2**63, None), InputError, r"outside ±2\*\*62 ns"),
    ],
)
def test_synchronizer_rejects_bad_stamps(call: Any, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        call(Synchronizer())


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"max_difference": 0.02}, InputTypeError, "max_difference must be an int"),
        ({"max_difference": -5}, InputError, "at least 0 ns, got -5"),
        ({"offset": 0.5}, InputTypeError, "offset must be an int"),
        ({"max_queue": 0}, InputError, "max_queue must be at least 1, got 0"),
        ({"max_queue": 2.5}, InputTypeError, "max_queue must be an int"),
        ({"ordered": "yes"}, InputTypeError, "ordered must be True or False"),
    ],
)
def test_synchronizer_rejects_bad_settings(
    kwargs: dict[str, Any], error: type[Exception], match: str
) -> None:
    with pytest.raises(error, match=match):
        Synchronizer(**kwargs)
