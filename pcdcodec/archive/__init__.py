"""Compressing an archive of RGB-D inputs on a Dask cluster: resumable, verified, in parallel.

:func:`archive` turns every input under the given paths (anything :func:`pcdcodec.open_source`
reads: bags, folders, camera recordings) into one ``.pcdc`` file under the output folder,
mirroring the source tree. It runs on a ``dask.distributed`` cluster: a local one sized to the
machine, or an existing one given by its scheduler address (for SLURM, start one with
``dask-jobqueue``; see ``docs/archive.md``). Needs the ``archive`` extra (``distributed``).

How a run is organised:

* **Segments.** A long input is cut into segments (:func:`segment_plan`: about
  :data:`SEGMENT_BYTES` of source and at least :data:`SEGMENT_MIN_FRAMES` frames each by
  default, lengths a multiple of the color keyframe interval). Each segment is one task that
  opens the source, seeks to its first frame and writes a recording with a new color encoder,
  so it starts with a keyframe and holds whole keyframe intervals. Folders seek by
  frame number; bags through a frame index the probe builds from the message headers
  (:meth:`pcdcodec.sources.Source.frame_index`), so a segment reads only its own messages.
  When all of an input's segments are written, a join task copies their messages into one
  recording (:func:`pcdcodec.recording.join`), which reads exactly like a file from one
  writer.
* **Manifest.** ``OUT/pcdcodec-archive.json`` records each input's size, modification time,
  content hash (BLAKE2b), frame count, segments, state and error. A rerun skips inputs that are
  done and unchanged (same size and modification time, same codecs), keeps the segments of a
  half-done input whose hash and plan are unchanged, and redoes the rest.
* **Atomic outputs.** Every file is written under a hidden name beside it (see
  :mod:`pcdcodec._atomic`; unique per writer) and renamed when complete, so a final name never
  holds a half-written file.
* **Lock.** ``OUT/pcdcodec-archive.lock`` (an OS file lock, released by the kernel if the run
  dies) refuses a second run on the same folder.
* **Verification.** With ``verify``, every output is decoded: depth and timestamps are compared
  bit-exactly with the source read again from disk, color with a hash of each frame as the
  codec decoded its own segment. Sources are deleted only after that, and only when asked.
* **Faults.** A task whose worker dies is rerun elsewhere by Dask; an input that fails (corrupt,
  unreadable) is reported and the others go on; a full disk stops the run with a clear error.

The modules: :mod:`~pcdcodec.archive.discover` (the inputs, their sizes and hashes),
:mod:`~pcdcodec.archive.plan` (segments), :mod:`~pcdcodec.archive.tasks` (what the workers
run), :mod:`~pcdcodec.archive.manifest` (manifest, lock, half-written files, a full disk),
:mod:`~pcdcodec.archive.settings` (a run's checked settings), :mod:`~pcdcodec.archive.run`
(:func:`archive` and the cluster) and :mod:`~pcdcodec.archive.summary` (what a run reports).
"""

from __future__ import annotations

from .discover import find_inputs
from .manifest import DONE_STATES as DONE_STATES
from .manifest import LOCK as LOCK
from .manifest import MANIFEST as MANIFEST
from .manifest import PARTS as PARTS
from .plan import SEGMENT_BYTES as SEGMENT_BYTES
from .plan import SEGMENT_MIN_FRAMES as SEGMENT_MIN_FRAMES
from .plan import segment_plan
from .run import archive
from .summary import ArchiveItem, ArchiveSummary
from .tasks import NO_CAMERA_HINT as NO_CAMERA_HINT

__all__ = ["ArchiveItem", "ArchiveSummary", "archive", "find_inputs", "segment_plan"]
