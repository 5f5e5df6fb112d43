"""Where the work runs: worker processes on this machine or a Dask cluster (docs/extending.md).

==================  ====================================================================================
:mod:`.local`       worker pools forked here (or by a fork server), kept between calls, jobs and requests
:mod:`.cluster`     a Dask cluster's workers, for extraction and evaluation beyond one machine
:mod:`.threads`     BLAS and OpenCV on one thread while scans are extracted, counted across threads
:mod:`.memory`      where extraction's large temporaries come from (glibc's allocator)
:mod:`.processes`   worker processes that end with the process that started them
==================  ====================================================================================
"""
