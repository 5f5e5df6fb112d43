"""``python -m texplorer``: the ``texplorer`` command, for environments whose scripts folder is not on the path
(a notebook kernel, ``python -m`` in CI)."""

import sys

from scanner.cli import main

sys.exit(main())
