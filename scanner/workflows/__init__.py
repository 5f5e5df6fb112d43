"""The workflows that the CLI, the web application, replay and the benchmarks share, each written once, one
module per subject so that a command imports only what it runs (``texplorer classify`` neither the
simulator nor the devices):

- :mod:`~scanner.workflows.database` -- **a database's features**: :func:`database_sources`
  turns catalog rows into :class:`features.ScanSource` objects keyed by the scan's content hash;
  :func:`extract_database` extracts them with the database as the cache (a second run over unchanged scans
  only reads it); :func:`stored_features` gives one stored scan's values.
- :mod:`~scanner.workflows.exchange` -- **a database exported with its features**: :func:`export_database`
  writes an export bundle (:func:`scanner.storage.bundle.export_bundle`) whose feature tables come from the
  cache.
- :mod:`~scanner.workflows.demo` -- **the simulated side**: :func:`simulated_database` (``texplorer demo``)
  extracts each simulated scan's features while it is in memory and fills the feature cache as the scans
  are stored; :func:`compile_kernels` (``make install``) extracts simulated scans so that numba writes every
  kernel the features use into its cache before the first command needs it.
- :mod:`~scanner.workflows.models` -- **the database's models**: :func:`train_default_model` trains the
  default one (``texplorer demo``, beside the evaluation), :func:`save_model_version` keeps a model as the
  database's next version, :func:`retrain` trains and keeps one on every scan; :func:`default_model` finds
  the current version, which ``serve`` and ``classify`` use when no model is given, and :func:`model_file`
  resolves a ``--model`` value (a version or a file).
- :mod:`~scanner.workflows.predictions` -- **a scan's top k with names**: :func:`predict_scan` extracts a
  scan's features and names the model's most probable labels with the taxonomy the caller gives (a
  database's own taxonomy, with its lab codes, where there is a database); :func:`name_predictions` names
  predictions made elsewhere; :func:`check_label` sets the operator's label against them.
- :mod:`~scanner.workflows.quick` -- **the quick scan**: :func:`quick_evaluation` (``evaluate --quick``) and
  :class:`QuickIdentifier`, the live side of ``scan --quick`` and the web app's quick identification.

The package sits above storage, features, learning and acquisition and below the CLI and the web
application, which call it rather than wiring those layers together themselves (see ``docs/extending.md``).
"""
