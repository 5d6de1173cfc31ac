"""Dask plugins of the local cluster (imports ``distributed``: imported only where a cluster
is made, so that ``qdrefine.distributed`` itself does not need Dask)."""

from __future__ import annotations

from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin


class NoProfiler(WorkerPlugin):
    """Stops a worker's statistical profiler (its periodic callbacks ``profile`` and
    ``profile-cycle``), also in a worker restarted after a kill: plugins are set up in
    every worker that joins."""

    name = "qdrefine-no-profiler"

    def setup(self, worker: Any) -> None:
        for key in ("profile", "profile-cycle"):
            callback = worker.periodic_callbacks.pop(key, None)
            if callback is not None:
                callback.stop()
