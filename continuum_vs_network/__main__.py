"""``python -m continuum_vs_network`` is the ``cvn`` command."""

import sys

from .cli import main

sys.exit(main())
