"""Import of other labs' recordings (``docs/ingest.md``): files + a TOML mapping -> Recordings.

A small TOML mapping file says which files belong together, how to read them and which column or variable
plays which channel role; :func:`ingest` applies it to a folder and returns the :class:`scanner.Recording`
objects and a report of every file it could not use (a bad file is named and skipped, the import goes on).
The mapping format, with an example, is in ``docs/ingest.md``.

Formats: CSV/TSV (header or not, trailing delimiters, ``nan``/``-nan``/empty tokens, a timestamp column
from which the rate is derived or a given rate, comment lines), WAV, NPY, NPZ and MATLAB v5 ``.mat``. A
recording may span several files sharing a stem (one file per sensor topic at different rates); a channel
may be spread over several columns of one row as consecutive samples (22 vibration samples per 100 Hz row
-> one 2200 Hz channel). Labels come from folder names, a label CSV or the file-name pattern; group ids
(object, trial, motion, ...) from the named groups of a file-name pattern.

Imported recordings are stored in a database folder as ``recordings/<set>/<recording>.mat`` (MATLAB v5,
one variable per channel plus a ``meta`` struct), written to a temporary folder first and renamed into
place, so a set is either complete or absent; :func:`load_recordings` reads a set back.

The package holds one step each: :mod:`.mapping` (the TOML mapping), :mod:`.readers` (one reader per file
format), :mod:`.alignment` (a common time base), :mod:`.assembly` (recordings from a folder) and :mod:`.sets`
(stored recording sets). Their public names are imported here.
"""

from scanner.storage.ingest.alignment import GAP_STEPS, Aligned, align, gaps
from scanner.storage.ingest.assembly import (
    IngestReport,
    Made,
    ingest,
    patches,
    recording_names,
    safe_name,
    split_of,
    stem_of,
)
from scanner.storage.ingest.mapping import (
    DEFAULT_CHANNELS,
    FORMATS,
    IMAGE_EXTENSIONS,
    MISSING,
    SPLIT_NAMES,
    TIME_UNITS,
    ChannelMap,
    FileMap,
    IngestError,
    IngestMapping,
    default_mapping,
    format_of,
    load_mapping,
    parse_grid,
    parse_mapping,
    with_excluded,
    with_grid,
    with_label_pattern,
)
from scanner.storage.ingest.readers import (
    MAX_ARRAY_BYTES,
    NAN_TOKENS,
    NOTE_KINDS,
    RATE_TOLERANCE,
    Note,
    Stream,
    file_format,
    rate_from_times,
    read_file,
    read_image,
    read_streams,
    read_table,
    seconds_of,
    summarise_notes,
)
from scanner.storage.ingest.sets import (
    MAPPING,
    RECORDINGS,
    SetWriter,
    load_recordings,
    read_recording,
    recording_sets,
    recording_variables,
    recover_sets,
    set_folder,
    store_recordings,
    write_recording,
)

__all__ = [
    "FORMATS", "IMAGE_EXTENSIONS", "TIME_UNITS", "MISSING", "SPLIT_NAMES", "IngestError", "ChannelMap", "FileMap",
    "IngestMapping", "DEFAULT_CHANNELS", "format_of", "parse_grid", "parse_mapping", "default_mapping",
    "with_grid", "with_label_pattern", "with_excluded", "load_mapping", "NAN_TOKENS", "MAX_ARRAY_BYTES",
    "RATE_TOLERANCE",
    "read_table", "Note",
    "NOTE_KINDS", "summarise_notes", "seconds_of", "rate_from_times", "read_image", "file_format", "Stream",
    "read_streams", "read_file", "GAP_STEPS", "gaps", "Aligned", "align", "IngestReport", "stem_of",
    "recording_names", "split_of", "safe_name", "patches", "ingest", "RECORDINGS", "recording_variables",
    "read_recording", "write_recording", "set_folder", "store_recordings", "load_recordings", "recording_sets",
    "SetWriter", "recover_sets", "Made", "MAPPING",
]
