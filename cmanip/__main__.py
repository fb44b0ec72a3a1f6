"""``python -m cmanip``: the same as the ``cmanip`` command."""

import sys

from cmanip.cli import main

sys.exit(main())
