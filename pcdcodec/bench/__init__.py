"""Comparison tooling research code imports; the core (codecs, recordings, projector, sources)
never imports this package.

* :mod:`~pcdcodec.bench.evaluation`: :func:`~pcdcodec.evaluate`, measuring codecs on a sequence;
  its rows are in :mod:`~pcdcodec.bench.results`, the :class:`~pcdcodec.Evaluation` and its
  report in :mod:`~pcdcodec.bench.report`, the PNG plots in :mod:`~pcdcodec.bench.plots`, and
  the rows of peer libraries in :mod:`~pcdcodec.bench.peers`.
* :mod:`~pcdcodec.bench.depth_rd`: rate-distortion of lossy depth against its peers.
* :mod:`~pcdcodec.bench.roundtrip`: ``pcdcodec demo``'s write-and-read measurement.
* :mod:`~pcdcodec.bench.pytest_plugin`: the pytest-benchmark plugin (fixtures, summary table).
* :mod:`~pcdcodec.bench.damage`: what ``recover`` must give back of a recording with flipped
  bytes, worked out from the undamaged file (the tests and ``scripts/recover_damage.py``).
* :mod:`~pcdcodec.bench.bag_peers`: a whole bag under the tools bags are kept small with (MCAP
  zstd, ROS 1 lz4, Cloudini), read and rewritten by :mod:`~pcdcodec.bench.bag_stream`.
* :mod:`~pcdcodec.bench.sequences` and :mod:`~pcdcodec.bench.sparse`: the sequences the
  repository's tests and benchmarks run on, and sparse depth made from them.
"""

from __future__ import annotations

__all__: list[str] = []
