"""Imported in every worker process of qdrefine's local clusters (a Dask ``preload``).

A terminal's Ctrl-C goes to the whole process group: the client, and the worker processes
of its local cluster. The client stops the run, removes its temporary store and closes the
cluster; the workers ignore SIGINT, instead of each printing its own traceback.
"""

from __future__ import annotations

import signal
import threading

if threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, signal.SIG_IGN)
