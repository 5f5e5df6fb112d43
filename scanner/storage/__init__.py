"""Storage of scans and recordings: the database, its file formats, imports and export bundles.

=====================  ===================================================================================
module                 holds
=====================  ===================================================================================
:mod:`.files`          crash-safe writes (temporary file, fsync, rename) and checksums of every stored byte
:mod:`.mat5`           reading MATLAB v5 files with bounded memory, whatever their bytes
:mod:`.matfile`        the ``.mat`` scan format: one file per scan, photos as PNG beside it
:mod:`.stored`         stored scans loaded where they are processed (here or on a cluster worker)
:mod:`.database`       the scan database: the files plus a SQLite catalog and the feature cache
:mod:`.ingest`         other labs' recordings: files + a TOML mapping -> recordings, stored as ``.mat``
:mod:`.bundle`         export bundles for other labs, and their import into a database
=====================  ===================================================================================

The public names (``Database``, ``load_scan``, ``save_scan``, ...) are re-exported by :mod:`scanner`; a
module of the project imports the module that defines a name (``docs/extending.md``).
"""
