"""Does the RVL blob view logs follow the layout Rerun's reader parses (12-byte config header,
width and height as little-endian uint32, then nibbles read from the top of little-endian
32-bit words, 3 value bits and a continuation bit each, runs of zeros and non-zeros,
zigzag deltas)? An independent reader of that layout, written from its description."""
import struct, numpy as np, pcdcodec
from pcdcodec.ros.messages import compressed_depth_encode
depth = pcdcodec.load_sample()[3].depth
blob = compressed_depth_encode(depth, rvl=True)
fmt, qa, qb = struct.unpack_from("<iff", blob, 0)
w, h = struct.unpack_from("<II", blob, 12)
words = np.frombuffer(blob[20:], "<u4")
def nibbles():
    for word in words.tolist():
        for k in range(8):
            yield (word >> (28 - 4 * k)) & 0xF
it = nibbles()
def vle():
    value, shift = 0, 0
    while True:
        n = next(it)
        value |= (n & 7) << shift
        if not n & 8:
            return value
        shift += 3
out = np.zeros(w * h, np.int64); i = 0; prev = 0
while i < w * h:
    zeros = vle(); i += zeros
    nonzeros = vle()
    assert zeros or nonzeros, "an empty run: Rerun refuses it"
    for _ in range(nonzeros):
        p = vle(); prev += (p >> 1) ^ -(p & 1); out[i] = prev; i += 1
print("header", fmt, qa, qb, w, h, "| decoded equal:", i == w * h and np.array_equal(out.reshape(h, w), depth))
