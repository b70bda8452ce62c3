"""``rvl``: Wilson's RVL (run length + variable length) coding of 16-bit depth.

RVL is the depth coder of A. D. Wilson, "Fast Lossless Depth Image Compression" (ISS 2017),
and the ``rvl`` mode of ROS ``compressed_depth_image_transport``. The body written here is the
plain RVL bitstream, byte for byte what those implementations write for the same image:

* The pixels are read in raster order. Until all are consumed, write the number of zero pixels,
  then the number ``n`` of non-zero pixels that follow, then ``n`` codes, one per non-zero pixel:
  the difference to the previous non-zero pixel (the previous value starts at 0 and carries
  across runs), taken between unsigned 16-bit values as ROS does and zig-zag mapped to a
  non-negative number (``(d << 1) ^ (d >> 31)``). A run of zeros at the end is followed by a
  non-zero count of 0, so every run is a (zeros, non-zeros) pair.
* Each number is a variable-length code of 4-bit nibbles: 3 bits of the value per nibble, least
  significant group first, the nibble's high bit set when another nibble follows.
* Nibbles fill 32-bit words from the most significant nibble down, 8 per word, and the words are
  stored little-endian. A last, partial word has its nibbles in its high bits and zeros below,
  which read as zero-valued codes that a decoder ignores once every pixel is placed.

The code printed in Wilson's paper takes the differences of signed ``short`` values; that
agrees with ROS and with this module for depth below 32768. Encoding and decoding are
vectorised with numpy: no Python code runs per pixel, only a short loop per run of non-zero
pixels in the decoder and a few loops over nibble positions.
"""

from __future__ import annotations

import functools
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError
from .base import FrameCodec

__all__ = ["RVL"]

#: RVL counts are C ``int``s, so neither an image nor any code may reach 2**31.
_MAX_PIXELS = 2**31 - 1
#: 11 nibbles carry 33 bits, the first length that holds every 31-bit value.
_MAX_NIBBLES = 11
#: The largest zig-zag code of a difference between two uint16 values (d = +65535).
_MAX_DELTA_CODE = 2 * 65535


def _spread(values: npt.NDArray[np.intp]) -> tuple[npt.NDArray[np.uint64], npt.NDArray[np.intp]]:
    """Each value's code as its nibbles, first nibble in the low 4 bits, and their number.

    Writing a code is then peeling 4 bits at a time while the continuation bit is set.
    """
    rest = values.astype(np.uint64)
    codes = np.zeros(values.shape, dtype=np.uint64)
    counts = np.ones(values.shape, dtype=np.intp)
    shift = np.uint64(0)
    while True:
        # Values already written are 0 here and add nothing.
        more = rest >= 8
        codes |= ((rest & np.uint64(7)) | (more.astype(np.uint64) << np.uint64(3))) << shift
        if not more.any():
            return codes, counts
        counts += more
        rest >>= np.uint64(3)
        shift += np.uint64(4)


@functools.cache
def _delta_codes() -> npt.NDArray[np.uint32]:
    """Code of every difference of two uint16 values, indexed by the signed difference.

    The low 24 bits hold the code's nibbles as :func:`_spread` lays them out, the top 4 bits
    their number. Negative differences sit at the end, where negative indices find them.
    """
    delta = np.arange(2 * 65535 + 1, dtype=np.int64)
    delta[65536:] -= delta.size
    codes, counts = _spread((delta << 1) ^ (delta >> 63))
    table: npt.NDArray[np.uint32] = (codes | (counts.astype(np.uint64) << np.uint64(28))).astype(
        np.uint32
    )
    return table


def _count_codes(
    counts: npt.NDArray[np.intp],
) -> tuple[npt.NDArray[np.uint64], npt.NDArray[np.intp]]:
    """Spread codes and nibble counts of run lengths, from the difference table when it can."""
    if counts.size and int(counts.max()) > _MAX_DELTA_CODE:
        return _spread(counts)
    # A value v is the zig-zag code of the difference (v >> 1) ^ -(v & 1): same table entry.
    packed = _delta_codes()[(counts >> 1) ^ -(counts & 1)]
    return (packed & 0xFFFFFF).astype(np.uint64), (packed >> 28).astype(np.intp)


def _put(
    stream: npt.NDArray[np.uint8], where: npt.NDArray[np.intp], codes: npt.NDArray[Any]
) -> None:
    """Write spread codes into a nibble stream, the first nibble of each at ``where``.

    Each nibble goes out with whatever bits sit above it in its byte; the packer drops them.
    """
    while where.size:
        nibble = codes.astype(np.uint8)
        stream[where] = nibble
        more = nibble >= 8
        where = where[more] + 1
        codes = codes[more] >> 4


def _segment_mask(lengths: npt.NDArray[np.intp]) -> npt.NDArray[np.bool_]:
    """Consecutive segments of the given lengths, alternately False and True, as one mask."""
    pattern = np.zeros(lengths.size, dtype=np.bool_)
    pattern[1::2] = True
    return np.repeat(pattern, lengths)


def rvl_encode(flat: npt.NDArray[np.uint16]) -> bytes:
    """The RVL body of a flat uint16 depth image (no header; ROS compressedDepth uses it too)."""
    npix = flat.size
    nonzero = flat != 0
    # Where the non-zero runs start and end (exclusive), alternately.
    edges = np.flatnonzero(np.diff(nonzero, prepend=False, append=False))
    run_start = edges[0::2]
    run_end = edges[1::2]
    nruns = run_start.size
    # One (zeros, non-zeros) pair per run, plus a (zeros, 0) pair for trailing zeros.
    last_end = int(run_end[-1]) if nruns else 0
    tail = last_end < npix
    npairs = nruns + int(tail)
    pairs = np.zeros(2 * npairs, dtype=np.intp)
    if nruns:
        pairs[0] = run_start[0]
        np.subtract(run_start[1:], run_end[:-1], out=pairs[2 : 2 * nruns : 2])
        np.subtract(run_end, run_start, out=pairs[1 : 2 * nruns : 2])
    if tail:
        pairs[-2] = npix - last_end
    pair_codes, pair_lengths = _count_codes(pairs)
    zeros_nibbles = pair_lengths[0::2]
    pair_nibbles = zeros_nibbles + pair_lengths[1::2]

    values = flat[nonzero]
    deltas = np.empty(values.size, dtype=np.intp)
    if values.size:
        deltas[0] = values[0]
        np.subtract(values[1:], values[:-1], out=deltas[1:], dtype=np.intp)
    codes = _delta_codes()[deltas]
    del deltas

    # Stream position of each difference's first nibble: the nibbles of the differences before
    # it, plus those of the pairs before it, which are added at the first difference of a run.
    length = (codes >> 28).astype(np.intp)
    where = length.copy()
    first_code = np.zeros(nruns, dtype=np.intp)
    np.cumsum(pairs[1 : 2 * nruns - 1 : 2], out=first_code[1:])
    where[first_code] += pair_nibbles[:nruns]
    np.cumsum(where, out=where)
    total = int(where[-1]) if where.size else 0
    where -= length
    pair_where = where[first_code] - pair_nibbles[:nruns]
    if tail:
        pair_where = np.append(pair_where, total)
        total += int(pair_nibbles[-1])

    stream = np.zeros(-(-total // 8) * 8, dtype=np.uint8)
    # Each difference's first nibble goes out in one scatter of the code's low byte (the high
    # half is cleared below); the longer codes then add their further nibbles level by level.
    stream[where] = codes.astype(np.uint8)
    multi = np.flatnonzero(length > 1)
    _put(stream, where[multi] + 1, codes[multi] >> 4)
    # The pair codes: a zero count, then the non-zero count right after it.
    _put(stream, pair_where, pair_codes[0::2])
    _put(stream, pair_where + zeros_nibbles, pair_codes[1::2])
    # Two nibbles per byte, first one high; then each word's bytes reversed, as a little-endian
    # store of a word filled from its most significant nibble leaves them.
    packed = stream[0::2] << 4
    packed |= stream[1::2] & 15
    return packed.view(">u4").astype("<u4").tobytes()


def rvl_decode(body: memoryview, npix: int) -> npt.NDArray[np.uint16]:
    """The ``npix`` flat uint16 depth values of an RVL body; :class:`DecodeError` when malformed."""
    if npix > _MAX_PIXELS:
        raise DecodeError(f"RVL frame has {npix} pixels, more than RVL's limit of {_MAX_PIXELS}")
    if body.nbytes == 0 or body.nbytes % 4:
        raise DecodeError(f"RVL body is {body.nbytes} bytes, not a positive multiple of 4")
    as_bytes = np.frombuffer(body, dtype="<u4").astype(">u4").view(np.uint8)
    stream = np.empty(2 * as_bytes.size, dtype=np.uint8)
    np.right_shift(as_bytes, 4, out=stream[0::2])
    np.bitwise_and(as_bytes, 15, out=stream[1::2])
    if stream[-1] & 8:
        raise DecodeError("RVL body ends inside a code (its last nibble says another follows)")

    # A nibble with a clear high bit ends a code and holds its most significant group; the
    # continuation nibbles before it hold the lower groups. Most codes are one or two nibbles,
    # so first compute, at every nibble, the value of a code of up to two nibbles ending there,
    # with bit 7 set when the code is longer; then gather that at the code ends.
    cont = stream >> 3
    value = stream.copy()
    cur = value[1:]
    cur <<= cont[:-1] * np.uint8(3)
    cur |= stream[:-1] & (cont[:-1] * np.uint8(7))
    value[2:] |= (cont[1:-1] & cont[:-2]) << 7
    ends = np.flatnonzero(cont == 0)
    nsym = ends.size
    value = np.take(value, ends)
    longer = np.flatnonzero(value >= 128)
    value &= 127
    symbols = value.astype(np.int32)
    # The rare longer codes: Horner steps over their remaining nibbles, back to front.
    where = ends[longer] - 2
    nibble = stream[where]
    length = 2
    while longer.size:
        length += 1
        if length > _MAX_NIBBLES:
            raise DecodeError(
                f"RVL code ending at nibble {int(ends[longer[0]])} is longer than "
                f"{_MAX_NIBBLES} nibbles, more than a 32-bit int holds"
            )
        high = symbols[longer]
        if length == _MAX_NIBBLES and int(high.max()) >= 1 << 28:
            raise DecodeError("RVL code does not fit in a signed 32-bit int")
        high <<= 3
        high |= nibble & 7
        symbols[longer] = high
        where -= 1
        # A code starting at nibble 0 looks at nibble -1, the last, whose high bit is clear.
        nibble = stream[where]
        more = nibble >= 8
        longer = longer[more]
        where = where[more]
        nibble = nibble[more]

    # Find the (zeros, non-zeros) pairs: each pair's non-zero count says how many difference
    # codes to skip to the next pair. This is the only sequential step, two Python operations
    # per run of non-zero pixels; it runs on to the end of the codes (the padding makes a few
    # extra (0, 0) pairs), and the run lengths are checked afterwards, vectorised.
    counts_at = symbols.data[1:]
    heads: list[int] = []
    add = heads.append
    at = 0
    try:
        while True:
            add(at)
            at += counts_at[at] + 2
    except IndexError:
        pass
    if heads[-1] >= nsym - 1:
        del heads[-1]  # not a whole pair
    pair_at = np.array(heads, dtype=np.intp)
    zeros = symbols[pair_at].astype(np.intp)
    counts = symbols[pair_at + 1].astype(np.intp)
    covered = np.cumsum(zeros + counts)
    last = int(np.searchsorted(covered, npix))
    if last == covered.size:
        done = int(covered[-1]) if covered.size else 0
        raise DecodeError(
            f"RVL body ends after {nsym} codes with {npix - done} of {npix} pixels still to decode"
        )
    if covered[last] > npix:
        raise DecodeError(
            f"RVL run lengths cover {int(covered[last])} pixels, the frame has {npix}"
        )
    pair_at = pair_at[: last + 1]
    zeros = zeros[: last + 1]
    counts = counts[: last + 1]
    at = int(pair_at[-1] + 2 + counts[-1])
    if at > nsym:
        raise DecodeError(
            f"RVL body ends {at - nsym} difference codes short of the last run of non-zeros"
        )
    used = int(ends[at - 1]) + 1
    if stream.size - used >= 8 or stream[used:].any():
        raise DecodeError(
            f"RVL body has {stream.size - used} nibbles after the last pixel; "
            "only zero padding within the last word is allowed"
        )

    spans = np.full(2 * pair_at.size, 2, dtype=np.intp)
    spans[1::2] = counts
    codes = symbols[:at][_segment_mask(spans)]
    if codes.size and int(codes.max()) > _MAX_DELTA_CODE:
        raise DecodeError(
            f"RVL difference code {int(codes.max())} is larger than any uint16 difference"
        )
    sign = codes & 1
    np.negative(sign, out=sign)
    codes >>= 1
    codes ^= sign
    values = np.cumsum(codes, dtype=np.int32)
    # Every partial sum is checked, so a corrupt run cannot wrap back into range unnoticed.
    if values.size:
        low, high_value = int(values.min()), int(values.max())
        if low < 1 or high_value > 65535:
            bad = low if low < 1 else high_value
            raise DecodeError(f"RVL non-zero pixel decodes to {bad}, outside 1..65535")
    runs = np.empty(2 * pair_at.size, dtype=np.intp)
    runs[0::2] = zeros
    runs[1::2] = counts
    image = np.zeros(npix, dtype=np.uint16)
    image[_segment_mask(runs)] = values
    return image


class RVL(FrameCodec):
    """Depth as an RVL bitstream (Wilson 2017), as ROS ``compressed_depth`` writes in rvl mode.

    RVL codes runs of zero pixels (no measurement) and the differences between consecutive
    valid pixels with 4-bit variable-length codes: simple, lossless, and fast both ways. It
    compresses Kinect-style depth about as well as LZ4 and has no parameters. uint16 only.
    The body is exactly the RVL bitstream, so ROS can read it once given the image size.
    """

    name: ClassVar[str] = "rvl"

    def __init__(
        self, *, max_error: float | None = None, max_rel_error: float | None = None
    ) -> None:
        self._set_bound(max_error, max_rel_error)

    def _encode_body(self, image: npt.NDArray[Any]) -> bytes:
        if image.size > _MAX_PIXELS:
            raise InputError(
                f"RVL counts are 32-bit: an image of {image.size} pixels is larger than "
                f"{_MAX_PIXELS}"
            )
        return rvl_encode(image.reshape(-1))

    def _decode_body(
        self, body: memoryview, shape: tuple[int, int], dtype: np.dtype[Any]
    ) -> npt.NDArray[Any]:
        return rvl_decode(body, shape[0] * shape[1]).reshape(shape)
