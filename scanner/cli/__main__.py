"""``python -m scanner.cli``: the ``texplorer`` command."""

import sys

from scanner.cli import main

sys.exit(main())
