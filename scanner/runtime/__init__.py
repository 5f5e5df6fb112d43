"""Where the work runs: worker processes on this machine or a Dask cluster, chosen once (docs/clusters.md).

A command or the web app makes one runtime current (:func:`chosen`: ``--workers`` for processes here, else
:func:`connect`: ``--scheduler``, Dask's configuration, else processes here); the code that runs work in
parallel asks :func:`current` and never branches on it.

======================  ================================================================================
:mod:`.executors`       the one interface (:class:`Runtime`) and its two implementations, chosen once
:mod:`.local`           worker pools forked here (or by a fork server), kept between calls, jobs and requests
:mod:`.cluster`         a Dask cluster's workers, for extraction and evaluation beyond one machine
:mod:`.threads`         BLAS and OpenCV on one thread while scans are extracted, counted across threads
:mod:`.memory`          where extraction's large temporaries come from (glibc's allocator)
:mod:`.processes`       worker processes that end with the process that started them
======================  ================================================================================
"""

from scanner.runtime.executors import LOCAL, DaskRuntime, LocalRuntime, Runtime, chosen, connect, current, using

__all__ = ["LOCAL", "DaskRuntime", "LocalRuntime", "Runtime", "chosen", "connect", "current", "using"]
