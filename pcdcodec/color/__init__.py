"""Color codecs: video stream codecs (see :class:`pcdcodec.codec.StreamCodec`)."""

from __future__ import annotations

__all__: list[str] = []
