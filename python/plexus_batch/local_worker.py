"""A Dask preload for the workers of plexus-batch's own LocalCluster (cli.py): they ignore SIGINT.

A terminal's Ctrl-C goes to the whole foreground process group, and the local workers are in it:
without this, a worker would die of it with a traceback, taking its shard with it. plexus-batch
handles the Ctrl-C instead (it cancels the tasks, writes the summary and closes the cluster, which
stops the workers). cli.py also ignores SIGINT while the cluster starts, so that the worker
processes start with it ignored; this covers a worker the nanny restarts later.
"""

from __future__ import annotations

import signal
import threading


def dask_setup(worker) -> None:  # noqa: ARG001 (Dask's preload interface)
    # The worker's event loop, which runs preloads, is its process's main thread under a nanny;
    # signal.signal works only there.
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
