"""Comparison tooling research code imports: the pytest-benchmark plugin, and (through
:mod:`pcdcodec.bench.evaluation`) codec evaluation, peers and plots.

The core (codecs, recordings, projector, sources) never imports this package.
"""

from __future__ import annotations

__all__: list[str] = []
