"""The camera topics' messages given back from a recording (``docs/format.md``, "Format
version 4: kept topics"): each envelope rebuilt with its frame's depth or color, each message
kept raw as it was, in file order (the input's log-time order).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterator
from typing import Any

from ..errors import DecodeError
from ..ros.envelope import Envelope, payload_of
from ..ros.kept import ENVELOPE_ENCODING, KeptMessage

__all__ = ["CameraAccess"]

#: Frames decoded for envelopes and kept for the next ones (a frame's depth and color
#: messages are logged close together, and pairs may be logged slightly out of frame order).
_CACHED_FRAMES = 8


class CameraAccess:
    """What a :class:`~pcdcodec.Recording` gives back of its camera topics."""

    path: Any
    timestamps: Any

    def frame(self, i: int) -> Any:  # provided by Recording
        raise NotImplementedError

    def _read_kept(self, camera: bool) -> Iterator[KeptMessage]:  # provided by KeptAccess
        raise NotImplementedError

    def camera_messages(self) -> Iterator[KeptMessage]:
        """The messages of the camera topics the frames were made of, as the input held
        them: each on its original topic (:attr:`camera_topics`: type, definition, encoding
        ``ros1``/``cdr``, connection facts), with its log time, in the input's order.

        A message made into a frame is rebuilt from its envelope and the frame: header,
        size, encoding, step, byte order and format exactly; a raw Image's pixels byte for
        byte where the frame is lossless (depth always; color with a lossless color codec),
        else within the color codec's quality; a PNG or compressedDepth depth image as a PNG
        (or RVL) of the same depth, bit for bit; JPEG color re-encoded at
        :data:`~pcdcodec.ros.envelope.JPEG_QUALITY`. Messages no frame holds come back as they
        were stored. Each frame is decoded once.

        With :meth:`kept_messages`, merged by log time, this is every message of the input's
        topics. Raises :class:`~pcdcodec.DecodeError` naming the file for an envelope that does
        not fit a frame of the recording, and as :meth:`kept_messages` does.
        """
        where = repr(str(self.path))
        index = {int(t): i for i, t in enumerate(self.timestamps)}
        cache: OrderedDict[int, Any] = OrderedDict()

        def frame(i: int) -> Any:
            if i in cache:
                cache.move_to_end(i)
                return cache[i]
            cache[i] = found = self.frame(i)
            if len(cache) > _CACHED_FRAMES:
                cache.popitem(last=False)
            return found

        for m in self._read_kept(True):
            topic = m.topic.original()
            if m.topic.message_encoding != ENVELOPE_ENCODING:
                yield KeptMessage(topic, m.log_time, m.data, m.publish_time)
                continue
            what = f"{where}: the {m.topic.camera} message of {m.topic.topic!r} at {m.log_time} ns"
            env = Envelope.unpack(m.data, what)
            i = index.get(env.timestamp)
            if i is None:
                raise DecodeError(
                    f"{what}: its envelope names the frame at {env.timestamp} ns, which the "
                    "recording does not hold"
                )
            f = frame(i)
            image = f.depth if m.topic.camera == "depth" else f.color
            if image is None:
                raise DecodeError(f"{what}: the frame at {env.timestamp} ns has no color")
            payload = payload_of(env.layout, image, what)
            if env.layout.startswith("image:") and len(env.head) + len(payload) != env.length:
                raise DecodeError(
                    f"{what}: the frame at {env.timestamp} ns gives {len(payload)} bytes of "
                    f"pixels, the message held {env.length}"
                )
            yield KeptMessage(topic, m.log_time, env.rebuild(payload), m.publish_time)
