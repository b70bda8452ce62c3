"""PyTorch datasets over ``.pcdc`` recordings (the optional extra ``pcdcodec[torch]``).

:class:`RecordingDataset` reads any frame at random, :class:`IterableRecordingDataset` reads
them in order; both are safe in a ``DataLoader`` with worker processes (``docs/learning.md``).
:data:`FIELDS` lists what an item can hold; :data:`TRAINING_COLOR` is the color codec to record
training data with.
"""

from __future__ import annotations

from ..errors import PcdcodecError

try:
    import torch as _torch  # noqa: F401  (here to say how to install it)
except ImportError:
    raise PcdcodecError(
        'pcdcodec.torch needs PyTorch: pip install "pcdcodec[torch]" (or pip install torch)'
    ) from None

from .catalog import find_recordings
from .dataset import TRAINING_COLOR, IterableRecordingDataset, RecordingDataset
from .items import DEFAULT_FIELDS, FIELDS

__all__ = [
    "DEFAULT_FIELDS",
    "FIELDS",
    "TRAINING_COLOR",
    "IterableRecordingDataset",
    "RecordingDataset",
    "find_recordings",
]
