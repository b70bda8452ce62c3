"""The layouts of RGB-D folders: which files are a frame's depth and color, and their times.

Each layout (TUM lists, ``rgb/`` and ``depth/`` subfolders, one flat folder, glob patterns; see
:mod:`pcdcodec.sources.folder`) gives a list of :data:`Pair`, in time order. Only file names and
lists are read here, never images.
"""

from __future__ import annotations

import fnmatch
import itertools
import re
from pathlib import Path

from ..errors import InputError

__all__ = [
    "DEPTH_SUFFIXES",
    "FLAT_DEPTH",
    "IMAGE_SUFFIXES",
    "LOOKED_FOR",
    "NS_PER_S",
    "Pair",
    "folder_pairs",
    "seconds_to_ns",
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
DEPTH_SUFFIXES = (".png", ".tif", ".tiff", ".npy")
NS_PER_S = 1_000_000_000


_DECIMAL_SECONDS = re.compile(r"\d+(?:\.\d*)?")


def _read_list(path: Path, columns: int) -> list[tuple[int, list[str]]]:
    """A TUM list's rows, ``timestamp`` first, each with its time in int ns.

    Raises :class:`~pcdcodec.InputError` naming the file and line for a row of too few
    columns, a time that is not decimal seconds, or a time not after the row before's (the
    rows are frames in time order; equal or earlier times are not times).
    """
    rows: list[tuple[int, list[str]]] = []
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) < columns:
            raise InputError(f"{path}:{lineno}: expected {columns} columns, got {line!r}")
        if not _DECIMAL_SECONDS.fullmatch(parts[0]):
            raise InputError(
                f"{path}:{lineno}: timestamp {parts[0]!r} is not seconds (a decimal number "
                "such as 1305031229.528748)"
            )
        t = seconds_to_ns(parts[0])
        if rows and t <= rows[-1][0]:
            raise InputError(
                f"{path}:{lineno}: timestamp {parts[0]} is not after the line before's; the "
                "listed times must increase (files whose listed times are not times need "
                "depth_pattern= and color_pattern=, to pair them by name)"
            )
        rows.append((t, parts[:columns]))
    return rows


def seconds_to_ns(text: str) -> int:
    whole, _, frac = text.partition(".")
    return int(whole) * NS_PER_S + int((frac + "000000000")[:9])


#: (timestamp ns, color file or None for depth only, depth file)
Pair = tuple[int, Path | None, Path]


def _tum_pairs(
    root: Path, max_difference: int, dropped: dict[str, int]
) -> tuple[list[Pair], list[int]]:
    """The pairs of TUM lists, each at its color image's time, and each depth image's own
    listed time (TUM stamps color and depth apart): ``associations.txt`` as it is, else
    ``rgb.txt`` and ``depth.txt`` paired by the rule of every reader (:mod:`pcdcodec.sync`),
    the images left without a partner counted in ``dropped``."""
    assoc = root / "associations.txt"
    if assoc.exists():
        rows = _read_list(assoc, 4)
        depth_times = []
        for _, r in rows:
            if not _DECIMAL_SECONDS.fullmatch(r[2]):
                raise InputError(
                    f"{assoc}: depth timestamp {r[2]!r} of the line at {r[0]} is not seconds "
                    "(a decimal number such as 1305031229.528748)"
                )
            depth_times.append(seconds_to_ns(r[2]))
        return [(t, root / r[1], root / r[3]) for t, r in rows], depth_times
    depth = [(t, root / r[1]) for t, r in _read_list(root / "depth.txt", 2)]
    if not (root / "rgb.txt").exists():
        return [(t, None, d) for t, d in depth], [t for t, _ in depth]  # depth only
    from ..sync import associate

    rgb = [(t, root / r[1]) for t, r in _read_list(root / "rgb.txt", 2)]
    pairs = associate([t for t, _ in rgb], [t for t, _ in depth], max_difference=max_difference)
    dropped["color"] = len(pairs.unmatched_color)
    dropped["depth"] = len(pairs.unmatched_depth)
    return [(rgb[i][0], rgb[i][1], depth[j][1]) for i, j in pairs], [depth[j][0] for _, j in pairs]


#: What the layouts look for, for the error of a folder that matches none.
LOOKED_FOR = (
    "rgb.txt/depth.txt (TUM layout); rgb/ (or color/) and depth/ subfolders; or one folder of "
    "files named *depth* and *rgb*/*color* (frame_000001_depth.tiff, frame_000001_rgb.tiff); "
    "depth as 16-bit PNG/TIFF, float32 TIFF or .npy, color as PNG/JPEG/TIFF; other names "
    "need depth_pattern= and color_pattern="
)


def _files(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    return sorted(
        p for p in folder.iterdir() if p.suffix.lower() in suffixes and not p.name.startswith(".")
    )


def _color_dir(root: Path) -> Path | None:
    return next((root / n for n in ("rgb", "color") if (root / n).is_dir()), None)


def _subfolder_pairs(
    root: Path, fps: float, max_difference: int, dropped: dict[str, int]
) -> tuple[list[Pair], str]:
    """The pairs of ``rgb/`` (or ``color/``) and ``depth/``, paired by what the names carry:
    timestamps in both names, paired by the rule of every reader (:mod:`pcdcodec.sync`, within
    ``max_difference`` ns); else the frame number in each name (its last number: rgb00012.png
    pairs with depth00012.png); else, when neither says more, the file order, which needs as
    many color as depth images. Images left without a partner are counted in ``dropped``."""
    color_dir = _color_dir(root)
    depths = _files(root / "depth", DEPTH_SUFFIXES)
    if color_dir is None:
        return _named_pairs(None, depths, fps)  # depth only
    colors = _files(color_dir, IMAGE_SUFFIXES)
    color_times, depth_times = _name_times(colors), _name_times(depths)
    if color_times is not None and depth_times is not None:
        from ..sync import associate

        found = associate(color_times[0], depth_times[0], max_difference=max_difference)
        dropped["color"] = len(found.unmatched_color)
        dropped["depth"] = len(found.unmatched_depth)
        kept = [(colors[i], depths[j]) for i, j in found]
    else:
        by_color, by_depth = _numbered(colors), _numbered(depths)
        if by_color is None or by_depth is None:
            if len(colors) != len(depths):
                raise InputError(
                    f"{str(root)!r} holds {len(colors)} color and {len(depths)} depth images "
                    "whose names carry no frame numbers to pair them by, such as "
                    f"{(colors if by_color is None else depths)[0].name!r}; name each pair's "
                    "files with its frame number (rgb/000012.png and depth/000012.png), or "
                    "remove the images without a partner"
                )
            return _named_pairs(colors, depths, fps)
        common = sorted(by_color.keys() & by_depth.keys())
        if not common:
            raise InputError(
                f"{str(root)!r}: no color image has the frame number of a depth image (color "
                f"{colors[0].name!r}, depth {depths[0].name!r}); images pair by the last "
                "number in their names"
            )
        dropped["color"] = len(by_color) - len(common)
        dropped["depth"] = len(by_depth) - len(common)
        kept = [(by_color[n], by_depth[n]) for n in common]
    if not kept:
        raise InputError(
            f"{str(root)!r}: no color image is within max_difference {max_difference} ns of a "
            "depth image by the times in their names; pass a larger --max-difference"
        )
    return _named_pairs([c for c, _ in kept], [d for _, d in kept], fps)


def _numbered(paths: list[Path]) -> dict[int, Path] | None:
    """Files by the last number in their names; None when a name has none or two share one."""
    out: dict[int, Path] = {}
    for p in paths:
        found = re.findall(r"\d+", p.stem)
        if not found or int(found[-1]) in out:
            return None
        out[int(found[-1])] = p
    return out


# The word that says what a file holds, and the rest of the name that pairs it up.
FLAT_DEPTH = re.compile(r"^(.*?)[-_.]?depth(.*)$", re.IGNORECASE)
_FLAT_COLOR = re.compile(r"^(.*?)[-_.]?(?:rgb|color|colour)(.*)$", re.IGNORECASE)


def _flat_key(regex: re.Pattern[str], path: Path) -> str | None:
    m = regex.match(path.stem)
    return None if m is None else f"{m.group(1)}|{m.group(2) or ''}"


def _pair_by_key(
    root: Path,
    colors: dict[str, Path] | None,
    depths: dict[str, Path],
    what: str,
    rule: str = "a color file of the same name but for its kind (or give a depth-only folder)",
) -> tuple[list[Path] | None, list[Path]]:
    """Depth files and their color files, matched by key and sorted by depth file name;
    ``rule`` says, in the error for a file without its partner, what a partner is."""
    keys = sorted(depths, key=lambda k: depths[k].name)
    if colors is None:
        return None, [depths[k] for k in keys]
    alone = [depths[k].name for k in keys if k not in colors]
    alone += [colors[k].name for k in sorted(colors) if k not in depths]
    if alone:
        raise InputError(
            f"{str(root)!r}: {len(alone)} file(s) have no partner among the {what}, such as "
            f"{alone[0]!r}; every depth file needs {rule}"
        )
    return [colors[k] for k in keys], [depths[k] for k in keys]


def _flat_files(root: Path) -> tuple[list[Path] | None, list[Path]] | None:
    """The flat layout's files (files named *depth* and *rgb*/*color*), or None if none."""
    depths: dict[str, Path] = {}
    colors: dict[str, Path] = {}

    def add(found: dict[str, Path], key: str, p: Path) -> None:
        if key in found:  # frame_1_depth.png and frame_1_depth.tiff: which one is the frame?
            raise InputError(
                f"{str(root)!r}: {found[key].name!r} and {p.name!r} are the same frame's "
                "files; keep one, or pick files with depth_pattern= and color_pattern="
            )
        found[key] = p

    for p in _files(root, DEPTH_SUFFIXES + IMAGE_SUFFIXES):
        key = _flat_key(FLAT_DEPTH, p)
        if key is not None and p.suffix.lower() in DEPTH_SUFFIXES:
            add(depths, key, p)
        elif p.suffix.lower() in IMAGE_SUFFIXES and (key := _flat_key(_FLAT_COLOR, p)):
            add(colors, key, p)
    if not depths:
        return None
    return _pair_by_key(root, colors or None, depths, "*depth* and *rgb*/*color* files")


def _glob_key(pattern: str) -> re.Pattern[str]:
    """A regex whose groups are what the wildcards of a glob pattern match (``*``, ``?`` and
    ``[...]`` classes, ``[!...]`` negated; a ``[`` without its ``]`` is itself)."""
    parts = []
    i = 0
    while i < len(pattern):
        ch = pattern[i]
        if ch == "*":
            parts.append("(.*)")
        elif ch == "?":
            parts.append("(.)")
        elif ch == "[":
            start = i + 2 if pattern[i + 1 : i + 2] == "!" else i + 1
            end = pattern.find("]", start + 1)  # a "]" first in the class is one of its chars
            if end < 0:
                parts.append(re.escape(ch))
            else:
                # fnmatch's own regex for the class, "(?s:[...])\\Z", as a group
                regex = fnmatch.translate(pattern[i : end + 1])
                parts.append("(" + regex.removeprefix("(?s:").removesuffix(")\\Z") + ")")
                i = end
        else:
            parts.append(re.escape(ch))
        i += 1
    return re.compile("".join(parts) + r"\Z")


def _pattern_files(
    root: Path, depth_pattern: str, color_pattern: str | None
) -> tuple[list[Path] | None, list[Path]]:
    def matched(pattern: str) -> dict[str, Path]:
        if not isinstance(pattern, str) or not pattern or Path(pattern).is_absolute():
            raise InputError(
                f"a name pattern must be a glob relative to the folder, got {pattern!r}"
            )
        regex = _glob_key(pattern)
        out: dict[str, Path] = {}
        for p in sorted(root.glob(pattern)):
            rel = p.relative_to(root).as_posix()
            m = regex.match(rel)
            if p.is_file() and m is not None:
                out["|".join(m.groups())] = p
        return out

    depths = matched(depth_pattern)
    if not depths:
        raise InputError(f"{str(root)!r} holds no file matching depth_pattern {depth_pattern!r}")
    colors = None if color_pattern is None else matched(color_pattern)
    if colors is not None and not colors:
        raise InputError(f"{str(root)!r} holds no file matching color_pattern {color_pattern!r}")
    return _pair_by_key(
        root,
        colors,
        depths,
        f"files matching {depth_pattern!r} and {color_pattern!r}",
        "a color file whose wildcards match the same text (with 'depth/d*.png' and "
        "'rgb/c*.png', depth/d001.png pairs with rgb/c001.png), or no color_pattern for "
        "depth only",
    )


_SECONDS = re.compile(r"(?<![\d.])(\d{9,10})\.(\d{1,9})(?!\d|\.\d)")
_NANOSECONDS = re.compile(r"(?<!\d)(\d{18,19})(?!\d)")


def _name_times(paths: list[Path]) -> tuple[list[int], str] | None:
    """Timestamps (ns) the file names carry, and what they were read as; or None."""
    for regex, what in ((_SECONDS, "seconds"), (_NANOSECONDS, "nanoseconds")):
        times = []
        for p in paths:
            found = regex.findall(p.name)
            if len(found) != 1:
                break
            m = found[0]
            times.append(seconds_to_ns(".".join(m)) if what == "seconds" else int(m))
        else:
            if all(b > a for a, b in itertools.pairwise(times)):
                return times, what
    return None


def _named_pairs(
    colors: list[Path] | None, depths: list[Path], fps: float
) -> tuple[list[Pair], str]:
    """Timestamped pairs of files paired up already, and how the times were made."""
    stamped = _name_times(depths)
    if stamped is not None:
        times, what = stamped
        note = f"recorded: {what} in the depth file names"
    else:
        step = NS_PER_S / fps
        # Frame numbers in the names (frame-000012.png) keep the gaps of dropped frames.
        numbers = _frame_numbers(colors if colors is not None else depths)
        if numbers is not None:
            note = f"not recorded: frame numbers in the file names at {fps:g} fps, from 0"
        else:
            note = f"not recorded: file order at {fps:g} fps, from 0"
        numbers = numbers or list(range(len(depths)))
        times = [round((n - numbers[0]) * step) for n in numbers]
    cs: list[Path | None] = list(colors) if colors is not None else [None] * len(depths)
    return list(zip(times, cs, depths, strict=True)), note


def _frame_numbers(paths: list[Path]) -> list[int] | None:
    """The last number in each file name, when every name has one and they increase."""
    numbers = []
    for p in paths:
        found = re.findall(r"\d+", p.stem)
        if not found:
            return None
        numbers.append(int(found[-1]))
    if any(b <= a for a, b in itertools.pairwise(numbers)):
        return None
    return numbers


def folder_pairs(
    root: Path,
    layout: str,
    fps: float,
    max_difference: int,
    depth_pattern: str | None,
    color_pattern: str | None,
    dropped: dict[str, int],
) -> tuple[list[Pair], str, list[int] | None]:
    """The folder's pairs, how their times were made, and for TUM lists each depth image's own
    listed time (``None`` for the other layouts, whose pairs have one time); the images of TUM
    lists, and of ``rgb/`` and ``depth/`` subfolders, left without a partner are counted in
    ``dropped`` (see :func:`_subfolder_pairs`; the flat layout and name patterns pair by name
    and refuse a file without its partner)."""
    if layout not in ("auto", "tum", "folders", "flat"):
        raise InputError(f"layout must be 'auto', 'tum', 'folders' or 'flat', got {layout!r}")
    if depth_pattern is not None:
        colors, depths = _pattern_files(root, depth_pattern, color_pattern)
        return (*_named_pairs(colors, depths, fps), None)
    if color_pattern is not None:
        raise InputError("color_pattern needs depth_pattern too")
    if layout == "tum" or (layout == "auto" and (root / "depth.txt").is_file()):
        pairs, depth_times = _tum_pairs(root, max_difference, dropped)
        return pairs, "recorded (TUM lists)", depth_times
    if layout in ("auto", "folders") and (root / "depth").is_dir():
        return (*_subfolder_pairs(root, fps, max_difference, dropped), None)
    flat = _flat_files(root) if layout in ("auto", "flat") else None
    if flat is None:
        raise InputError(f"{str(root)!r} is not an RGB-D folder: expected {LOOKED_FOR}")
    return (*_named_pairs(*flat, fps), None)
