"""``python -m studies`` runs the ``precrel`` command line."""

import sys

from .cli import main

sys.exit(main())
