"""Mutations of encoded depth frames, shared by the fuzz test and ``tests/run_fuzz_depth.py``.

A decoder facing hostile bytes must raise :class:`pcdcodec.DecodeError` or give back exactly
the original image: never crash, hang, or return a wrong image. The mutations hit the body
far more often than the header, since the header is checked field by field before the body
decoder runs, and the body is where a compiled decoder could read or write out of bounds.
"""

from __future__ import annotations

import struct
from collections import Counter
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec.depth import FrameCodec, read_header

KINDS = ("bitflips", "bytes", "truncate", "extend", "garbage-body", "splice", "shape")


def _with_body(data: bytes, body: bytes) -> bytes:
    """``data``'s header, its body length field set to fit ``body``."""
    header = read_header(data)
    head = bytearray(data[: header.header_size])
    struct.pack_into("<Q", head, header.header_size - 12, len(body))
    return bytes(head) + body


def mutate(data: bytes, rng: np.random.Generator, other: bytes) -> tuple[str, bytes]:
    """One random mutation of an encoded frame; ``other`` is another frame of the same codec."""
    kind = KINDS[int(rng.integers(len(KINDS)))]
    header_size = read_header(data).header_size
    out = bytearray(data)
    body_len = len(data) - header_size
    if kind == "bitflips":
        for _ in range(int(rng.integers(1, 9))):
            # Nine times in ten inside the body.
            lo = header_size if body_len and rng.random() < 0.9 else 0
            pos = int(rng.integers(lo, len(out)))
            out[pos] ^= 1 << int(rng.integers(8))
        return kind, bytes(out)
    if kind == "bytes":
        for _ in range(int(rng.integers(1, 5))):
            out[int(rng.integers(len(out)))] = int(rng.integers(256))
        return kind, bytes(out)
    if kind == "truncate":
        cut = int(rng.integers(0, len(data)))
        if rng.random() < 0.5:  # a shorter body under a header that says so
            return kind, _with_body(
                data, data[header_size : header_size + max(0, cut - header_size)]
            )
        return kind, data[:cut]
    if kind == "extend":
        extra = rng.bytes(int(rng.integers(1, 64)))
        if rng.random() < 0.5:
            return kind, _with_body(data, data[header_size:] + extra)
        return kind, data + extra
    if kind == "garbage-body":
        return kind, _with_body(data, rng.bytes(int(rng.integers(0, max(2, 2 * body_len)))))
    if kind == "splice":
        # The start of this body, then the rest of another frame's.
        other_body = other[read_header(other).header_size :]
        cut = int(rng.integers(0, body_len + 1))
        return kind, _with_body(data, data[header_size : header_size + cut] + other_body[cut:])
    # "shape": the body under a header claiming another height and width.
    header = read_header(data)
    head = bytearray(data[:header_size])
    h = max(1, header.height + int(rng.integers(-3, 4)))
    w = max(1, header.width + int(rng.integers(-3, 4)))
    struct.pack_into("<II", head, header_size - 20, h, w)
    return kind, bytes(head) + data[header_size:]


def fuzz_frames(codec: FrameCodec, images: list[Any], cases: int, seed: int = 0) -> Counter[str]:
    """Decode ``cases`` mutated frames; assert each raises DecodeError or is exact.

    Returns how many cases of each kind raised, and how many decoded exactly
    (``"<kind>:exact"``). Anything else fails an assertion naming the case.
    """
    rng = np.random.default_rng(seed)
    encoded = [codec.encode(image) for image in images]
    outcome: Counter[str] = Counter()
    for case in range(cases):
        i = int(rng.integers(len(images)))
        kind, data = mutate(encoded[i], rng, encoded[(i + 1) % len(images)])
        try:
            decoded = codec.decode(data)
        except pcdcodec.DecodeError:
            outcome[kind] += 1
            continue
        expected = images[i]
        view = np.uint32 if expected.dtype.itemsize == 4 else np.uint16
        same = (
            decoded.shape == expected.shape
            and decoded.dtype == expected.dtype
            and np.array_equal(decoded.view(view), expected.view(view))
        )
        assert same, f"case {case} ({kind}, seed {seed}) decoded to a wrong image"
        outcome[f"{kind}:exact"] += 1
    return outcome


def fuzz_images(depths: list[Any], rng: np.random.Generator, count: int) -> list[Any]:
    """Small crops of real depth, as uint16 and as float32 metres, to keep each case fast."""
    images: list[Any] = []
    for _ in range(count):
        depth = depths[int(rng.integers(len(depths)))]
        h = int(rng.integers(1, 97))
        w = int(rng.integers(1, 97))
        y = int(rng.integers(0, depth.shape[0] - h + 1))
        x = int(rng.integers(0, depth.shape[1] - w + 1))
        crop = np.ascontiguousarray(depth[y : y + h, x : x + w])
        if rng.random() < 0.25:
            metres = (crop / 5000.0).astype(np.float32)
            metres[crop == 0] = np.nan
            images.append(metres)
        else:
            images.append(crop)
    return images
